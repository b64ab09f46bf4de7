"""The simulator's outputs pinned bit for bit (``feeder.sim.simulate.simulate``).

A refactoring of the simulation code must not change one bit of what it computes: each run below
is pinned by its final and initial yaws, its status list and its per-drop diagnostics
(tests/data/sim_pinned_golden.json, with the SHA-256 of each as before). The statuses and initial
yaws (from the seed alone) are equal on any machine; the final yaws and diagnostics to the bit under
the arithmetic they were recorded with (tests/pins.py) and within SIM_RTOL of the largest value
elsewhere. Bullet is one compiled binary without CPU dispatch and the chain uses scalar libm only:
the values are bit-identical on AVX2, AVX-512 and no-SIMD numpy/torch and on the issue #36 EPYC.
A difference that entered mid-run would grow (contacts are chaotic) and fail the test; no small
tolerance could hold it, and none is pretended. Together the runs exercise a one-piece part on a
straight fence (with and without slide skipping), a many-piece concave library part on curved and
straight fences (teleports, jams), the no-physics path, two lanes in one world, and the status
checks (ok, jammed, fell_off, flipped, timed_out) under tightened status settings. Presets and the
scene come from config/config.yaml. The runs of ``RUNS`` pin the pieces contact (the default until
2026-11-25, set explicitly: its values are unchanged since) and the square fence tip, those of
``DEFAULT_RUNS`` the default's contact model (footprint pads and outline slabs), fence tip and
preset (``sim.preset``).

A deliberate change of the physics, the config's ``scene`` / ``sim.presets`` or the pybullet
version changes these values: re-pin them (``python tests/test_sim_pinned.py`` writes the golden file).
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads: the re-pin (__main__) runs with the BLAS kernel pytest uses

# isort: on
import copy
import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from feeder.lane.fences import parse_location
from feeder.parts.geometry import load_part
from feeder.parts.shapes import shape_part
from feeder.sim.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]
CFG = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
SCENE, PRESETS = CFG["scene"], CFG["sim"]["presets"]
DIAG_KEYS = (
    "sim_time",
    "max_speed",
    "max_omega",
    "teleports",
    "skips",
    "inside_fence",
    "probe_yaw",
    "final_x",
    "final_y",
)

# (id, part: library id or shape spec, loc1, loc2, preset, drops, seed, preset overrides, scene status overrides)
RUNS = [
    ("rect_straight45_faithful", "rect-40x20", "straight:45", "none", "faithful", 3, 0, {}, {}),
    ("rect_straight45_fast", "rect-40x20", "straight:45", "none", "fast", 4, 0, {}, {}),
    ("rect_straight65_coarse_jams", "rect-40x20", "straight:65", "none", "coarse", 5, 0, {}, {}),
    ("gear8_curved30_straight45_coarse", "gear8-a", "curved:30", "straight:45", "coarse", 4, 0, {}, {}),
    ("gear8_straight30_curved45_fast", "gear8-a", "straight:30", "curved:45", "fast", 3, 0, {}, {}),
    ("rect60_two_lanes_fast", "rect-60x20", "straight:20", "straight:60", "fast", 5, 0, {"lanes": 2}, {}),
    ("no_fence_fast", "rect-40x20", "none", "none", "fast", 5, 0, {}, {}),
    (
        "statuses_a_coarse",
        "rect-40x20",
        "straight:45",
        "none",
        "coarse",
        6,
        0,
        {},
        {"lateral_limit": 0.08, "flip_tilt_deg": 0.23, "timeout_factor": 0.0, "timeout_extra_s": 1.9},
    ),
    (
        "statuses_b_coarse",
        "rect-40x20",
        "straight:45",
        "none",
        "coarse",
        6,
        2,
        {},
        {"lateral_limit": 0.08, "flip_tilt_deg": 0.23, "timeout_factor": 0.0, "timeout_extra_s": 1.9},
    ),
]

# under the default's contact model and preset (config/config.yaml: belt footprint pads, walls and fences on
# outline slabs, sim.preset)
DEFAULT_RUNS = [
    ("default_rect_straight45", "rect-40x20", "straight:45", "none", CFG["sim"]["preset"], 4, 0, {}, {}),
    ("default_gear8_straight30_curved45", "gear8-a", "straight:30", "curved:45", CFG["sim"]["preset"], 3, 0, {}, {}),
    ("default_lshape_curved30_straight45", "lshape-a", "curved:30", "straight:45", CFG["sim"]["preset"], 3, 0, {}, {}),
]
DEFAULT_IDS = {r[0] for r in DEFAULT_RUNS}
PIECES = {"belt": {"footprint": {"model": "pieces"}}, "part": {"wall_contact": {"model": "pieces"}}}

# computed from the simulator before the refactoring of run_drops (sim/drops.py, sim/body.py)
GOLDEN = Path(__file__).parent / "data" / "sim_pinned_golden.json"
SIM_RTOL = 1e-9


def _part(name: str):
    path = ROOT / "parts" / f"{name}.stl"
    return load_part(path) if path.is_file() else shape_part(name, 0.005)


def _sha(a: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()


def values(run) -> dict:
    name, part, loc1, loc2, preset, drops, seed, overrides, status = run
    scene = copy.deepcopy(SCENE)
    scene["status"].update(status)
    if name not in DEFAULT_IDS:  # the pieces contact and the square fence tip, as these runs were pinned
        for section, keys in PIECES.items():
            for key, value in keys.items():
                scene[section][key] = dict(scene[section][key], **value)
        scene["fences"].pop("tip", None)
    res = simulate(
        _part(part),
        parse_location(loc1),
        parse_location(loc2),
        drops,
        seed,
        scene,
        dict(PRESETS[preset], **overrides),
        preset,
        probe_x=-0.05,
        check_fences=True,
    )
    diag = res["diag"]
    return {
        "final": res["final_yaw_deg"].tolist(),
        "initial": res["initial_yaw_deg"].tolist(),
        "status": [str(s) for s in res["status"]],
        "diag": {k: np.asarray(diag[k]).tolist() for k in DIAG_KEYS},
        "sha256": {
            "final": _sha(res["final_yaw_deg"]),
            "initial": _sha(res["initial_yaw_deg"]),
            "diag": hashlib.sha256(b"".join(np.asarray(diag[k]).tobytes() for k in DIAG_KEYS)).hexdigest(),
        },
    }


@pytest.fixture(scope="module")
def golden() -> dict:
    return json.loads(GOLDEN.read_text())


@pytest.mark.parametrize("run", RUNS + DEFAULT_RUNS, ids=[r[0] for r in RUNS + DEFAULT_RUNS])
def test_simulation_matches_the_pinned_run(run, golden):
    from pins import assert_pinned, same_arithmetic

    got, want, recorded_on = values(run), golden["runs"][run[0]], golden["recorded_on"]
    assert got["status"] == want["status"]  # on any machine
    assert np.array(got["initial"]).tobytes() == np.array(want["initial"]).tobytes()  # on any machine
    assert_pinned(got["final"], want["final"], recorded_on, SIM_RTOL, what="final yaws")
    for k in DIAG_KEYS:
        assert_pinned(got["diag"][k], want["diag"][k], recorded_on, SIM_RTOL, what=k)
    if same_arithmetic(recorded_on):
        assert got["sha256"] == want["sha256"]


def test_the_pinned_runs_cover_every_reachable_status(golden):
    seen = {s for v in golden["runs"].values() for s in v["status"]}
    assert seen == {"ok", "jammed", "fell_off", "flipped", "timed_out"}


if __name__ == "__main__":  # re-pin: write tests/data/sim_pinned_golden.json
    from pins import arithmetic

    pinned = {
        "_about": "final and initial yaws (deg, NaN: not ok), statuses and per-drop diagnostics of the runs of "
        "tests/test_sim_pinned.py; sha256 of the float64 bytes as before; recorded_on: the arithmetic of the "
        "recording process (tests/pins.py)",
        "recorded_on": arithmetic("numpy", "pybullet"),
        "runs": {r[0]: values(r) for r in RUNS + DEFAULT_RUNS},
    }
    GOLDEN.write_text(json.dumps(pinned, indent=1) + "\n")


def test_feeder_asks_for_the_avx2_blas_kernel_where_it_runs(tmp_path):
    """feeder/__init__.py sets OPENBLAS_CORETYPE (before numpy loads OpenBLAS) where the processor has
    AVX2 and FMA and nobody chose a kernel: the pins above were computed with it, and OpenBLAS's
    AVX-512 kernels moved the lshape-a run by 0.36 mm on an AVX-512 EPYC."""
    from feeder import BLAS_KERNEL, _pin_blas_kernel

    def cpu(flags: str) -> Path:
        path = tmp_path / f"cpuinfo-{len(flags)}"
        path.write_text(f"processor\t: 0\nmodel name\t: x\nflags\t\t: {flags}\n\nprocessor\t: 1\nflags\t\t: {flags}\n")
        return path

    env: dict = {}
    assert _pin_blas_kernel(env, str(cpu("fpu sse2 avx avx2 fma avx512f"))) == BLAS_KERNEL == env["OPENBLAS_CORETYPE"]
    env = {}
    assert _pin_blas_kernel(env, str(cpu("fpu sse2 avx"))) is None and env == {}  # no AVX2: OpenBLAS chooses
    env = {"OPENBLAS_CORETYPE": "Zen"}
    assert _pin_blas_kernel(env, str(cpu("avx2 fma"))) == "Zen" and env == {"OPENBLAS_CORETYPE": "Zen"}  # the user's
    env = {}
    assert _pin_blas_kernel(env, str(tmp_path / "none")) is None and env == {}  # no /proc/cpuinfo (not Linux)
    # a fresh interpreter that imports feeder first runs OpenBLAS with that kernel where the processor has it
    code = "import feeder, numpy, os; print(os.environ.get('OPENBLAS_CORETYPE'))"
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == str(_pin_blas_kernel({}))
