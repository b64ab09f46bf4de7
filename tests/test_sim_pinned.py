"""The simulator's outputs pinned bit for bit (``feeder.sim.simulate.simulate``).

A refactoring of the simulation code must not change one bit of what it computes: each run below
is pinned by the SHA-256 of its final and initial yaws (``ndarray.tobytes()``), its exact status
list and a hash of the per-drop diagnostics. Together the runs exercise a one-piece part on a
straight fence (with and without slide skipping), a many-piece concave library part on curved and
straight fences (teleports, jams), the no-physics path, two lanes in one world, and the status
checks (ok, jammed, fell_off, flipped, timed_out) under tightened status settings. Presets and the
scene come from config/config.yaml.

A deliberate change of the physics, the config's ``scene`` / ``sim.presets`` or the pybullet
version changes these values: re-pin them (``python tests/test_sim_pinned.py`` prints the table).
"""

from __future__ import annotations

import copy
import hashlib
from pathlib import Path

import numpy as np
import pytest
import yaml

from feeder.parts.geometry import load_part
from feeder.parts.shapes import shape_part
from feeder.sim.fences import parse_location
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

# computed from the simulator before the refactoring of run_drops (sim/drops.py, sim/body.py)
EXPECTED = {
    "rect_straight45_faithful": {
        "final": "d641fa1aa5bf93e350eb9866616552868258c73a11843d2b3899f7edda835b6f",
        "initial": "e6ca11efcd28977fa07e64750b30b468aaaec419d0c122fb420700f1ae6fdbf4",
        "status": ["ok", "ok", "ok"],
        "diag": "4d700afb6dc646a4283301cbcfbca4ad50225e2474397ddb0f1d2e78a072e05b",
    },
    "rect_straight45_fast": {
        "final": "8a0d7fd472b83ec0cd22c7a29a311ca48de0aa751bd87569df7b1a376612fba2",
        "initial": "3b48436a0314323922fd2a80dc933288542c94add6d4044ab5a26a1d5169b1f4",
        "status": ["ok", "ok", "ok", "ok"],
        "diag": "1ad0279b11e1d3ba31020287ffe45f184ab438b83aaacd034d0a9be973e42bd4",
    },
    "rect_straight65_coarse_jams": {
        "final": "d44c50735fbae35e58402705be2d41ac54205aff5333529be79c6bfc1854c7ed",
        "initial": "500f4aa83e5969c717beb7b7645ac2780598dc3b1c1876caacf558f2b02371f4",
        "status": ["ok", "jammed", "ok", "jammed", "ok"],
        "diag": "d7d08ac555ca79189d7c51348cb252e9dc303344a146eb7717e55a315be8ff12",
    },
    "gear8_curved30_straight45_coarse": {
        "final": "46160df55439ad2eafc085adb0b31ff6b1a81263e8fd25b2d149bf5c101f1c38",
        "initial": "515a3f9f282fe27f820749d7e02474e3134cc8a59d05df253570065bb39992ad",
        "status": ["jammed", "ok", "ok", "jammed"],
        "diag": "6aa942bf3b1f365e2c4724fc3995b632f31d2bed83b80b9bbcc3282534eed3ad",
    },
    "gear8_straight30_curved45_fast": {
        "final": "3057399dcdbf01b4fc2c3eeb79d7684b42f5fe7a722cbd7e5a9636db33b553d5",
        "initial": "8a2b4a1f9ee7059ec537ae5411e07048f13d16f8590614c08e7ba658ed373e35",
        "status": ["ok", "ok", "ok"],
        "diag": "ad9ccf7a811e53ef2698bc01ffb73480928ae1db79177130b2c2f8d5fcc49708",
    },
    "rect60_two_lanes_fast": {
        "final": "c71e09dba5ea573bee6164ef4da91801e8e52c928ecaf3dbef4325abfd91aba8",
        "initial": "87fb21918e98865654d869c8580fef76b74fde5638a652e0f6ea981b3441e631",
        "status": ["ok", "ok", "ok", "ok", "ok"],
        "diag": "3212b96878011536188fcd64b537e6cd5df015603a50c90563aa068501c3d69f",
    },
    "no_fence_fast": {
        "final": "13afd3fed73d1d1d837c408903fa8d6d07702f7ed01985208671300f4786a479",
        "initial": "13afd3fed73d1d1d837c408903fa8d6d07702f7ed01985208671300f4786a479",
        "status": ["ok", "ok", "ok", "ok", "ok"],
        "diag": "b738f69e55091dd3376ff5ea545c98ae908716b08014ba46d17ba1b223eb17d2",
    },
    "statuses_a_coarse": {
        "final": "4cfd3da400c7d34e9be914bd344f69326387f4cb3161f2638edeaf163c60c419",
        "initial": "b56fbac56de292a95312aba2771117f93106fe6c184a5eb326d084b05cdc9ea7",
        "status": ["timed_out", "ok", "flipped", "timed_out", "ok", "ok"],
        "diag": "17d1e6f8d0efa12a646e6165107508732148a879c4e5d84bdf84d2d26eda5ca2",
    },
    "statuses_b_coarse": {
        "final": "ff5387f994cd7b48d176d06c06ef90b8a6fb668d593d52db530043bd47a327f1",
        "initial": "f555987c8f75554c4aa3bad1abc65cfe12e6a4e2fcb70094d6375ce0cbaa49dc",
        "status": ["flipped", "flipped", "timed_out", "flipped", "fell_off", "flipped"],
        "diag": "6758c36ee13ab4cd12ac36790db304baca5edea371668e35c0d99aba61962dc2",
    },
}


def _part(name: str):
    path = ROOT / "parts" / f"{name}.stl"
    return load_part(path) if path.is_file() else shape_part(name, 0.005)


def _sha(a: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()


def fingerprint(run) -> dict:
    _, part, loc1, loc2, preset, drops, seed, overrides, status = run
    scene = copy.deepcopy(SCENE)
    scene["status"].update(status)
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
        "final": _sha(res["final_yaw_deg"]),
        "initial": _sha(res["initial_yaw_deg"]),
        "status": [str(s) for s in res["status"]],
        "diag": hashlib.sha256(b"".join(np.asarray(diag[k]).tobytes() for k in DIAG_KEYS)).hexdigest(),
    }


@pytest.mark.parametrize("run", RUNS, ids=[r[0] for r in RUNS])
def test_simulation_is_bit_identical_to_the_pinned_run(run):
    assert fingerprint(run) == EXPECTED[run[0]]


def test_the_pinned_runs_cover_every_reachable_status():
    seen = {s for v in EXPECTED.values() for s in v["status"]}
    assert seen == {"ok", "jammed", "fell_off", "flipped", "timed_out"}


if __name__ == "__main__":  # print the table to re-pin
    import pprint

    pprint.pprint({r[0]: fingerprint(r) for r in RUNS}, width=120, sort_dicts=False)
