"""Which part of the start/teleport/stop shortcuts turns the L's drops under the round fence tip?
(issue #39; docs/testing.md, "Paired shortcut checks")

Under round tips ``tests/test_sim_physics.py`` finds the shortcuts of ``full_path: false`` turning
every drop of the L (``l-40x30x10``, ``straight:30`` + ``straight:45``, the test's short belt, 50
drops, ``PROOF`` settings) by about -0.25 deg against the full path. This runs the test's own
drops under one variant and compares them with the full path drop by drop
(``feeder.bench.designs.paired_basins``). The package is not changed: a variant replaces a
function of :mod:`feeder.sim.drops` or a scene value in this process only.

Variants (one per run; ``full`` first, it is the reference):

* ``full``: the full path (the test's baseline).
* ``shortcuts``: start/teleport/stop, as the test runs them.
* ``start_only``: the shortcut start, then the full path's stop (at the record point, no moves).
* ``stop_only``: the full path's start (``belt.start_y``), then the shortcut teleports and stop.
* ``margin<M>``: the shortcuts with ``status.approach_margin`` = M metres (start and teleports).
* ``long_belt``: the shortcuts with a belt slab 2 m longer (``status.timeout_extra_s`` + 20 s).
* ``<variant>_nosleep``: the part's sleeping disabled (``ACTIVATION_STATE_DISABLE_SLEEPING``).

    python docs/experiments/shortcut_start.py OUT_DIR VARIANT [VARIANT ...]

Each variant writes ``OUT_DIR/<variant>.npz`` (initial and final yaws, statuses, teleports) and
prints its comparison with ``OUT_DIR/full.npz``. About 40 s a variant on one core.
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads (feeder/__init__.py)

# isort: on
import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))

SCENE_KEY = ("l-40x30x10", "straight:30", "straight:45")


def run_variant(variant: str) -> dict:
    """The test's 50 drops of the L under ``variant`` (a fresh process per variant: it patches)."""
    import test_sim_physics as t

    from feeder.sim import body, drops

    if variant.endswith("_nosleep"):
        add = body.World.add_part

        def add_awake(self, *a, **k):
            b = add(self, *a, **k)
            self.pb.changeDynamics(
                b, -1, activationState=self.pb.ACTIVATION_STATE_DISABLE_SLEEPING, physicsClientId=self.cid
            )
            return b

        body.World.add_part = add_awake
        variant = variant[: -len("_nosleep")]
    status = t.SHORT_BELT["status"]
    if variant == "full":
        return t._run(SCENE_KEY, t.FULL)
    if variant == "start_only":
        drops.arrived = lambda world, ln, s, lim: s.y >= world.plan.record_y
    elif variant == "stop_only":
        drops.start_y = lambda plan, model, yaw, lim: float(t.SHORT_BELT["belt"]["start_y"])
        status["timeout_extra_s"] = float(status["timeout_extra_s"]) + 20.0  # the longer ride
    elif variant.startswith("margin"):
        status["approach_margin"] = float(variant[len("margin") :])
    elif variant == "long_belt":
        status["timeout_extra_s"] = float(status["timeout_extra_s"]) + 20.0
    elif variant != "shortcuts":
        raise SystemExit(f"unknown variant {variant!r}")
    return t._run(SCENE_KEY, dict(t.PROOF, lanes=1, skip_slides=False))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out_dir", type=Path)
    ap.add_argument("variants", nargs="+")
    args = ap.parse_args()
    if len(args.variants) > 1:  # one process each: a variant patches the package
        import subprocess

        for v in args.variants:
            subprocess.run([sys.executable, __file__, str(args.out_dir), v], check=True)
        return
    from feeder.bench.designs import paired_basins

    variant = args.variants[0]
    args.out_dir.mkdir(parents=True, exist_ok=True)
    r = run_variant(variant)
    np.savez(
        args.out_dir / f"{variant}.npz",
        initial=r["initial_yaw_deg"],
        final=r["final_yaw_deg"],
        status=r["status"],
        teleports=r["diag"]["teleports"],
    )
    ref = args.out_dir / "full.npz"
    if variant != "full" and ref.exists():
        f = np.load(ref)
        assert np.array_equal(f["initial"], r["initial_yaw_deg"])  # the same drops
        c = paired_basins(r["final_yaw_deg"], r["status"], f["final"], f["status"])
        print(
            f"{variant}: same basin {c['same_basin']:.3f}, median |dyaw| {c['median_dyaw_deg']:.3f} deg, "
            f"median signed {c['median_signed_dyaw_deg']:+.3f} deg, max {c['max_dyaw_deg']:.3f} deg, "
            f"teleports/drop {np.mean(r['diag']['teleports']):.1f}"
        )
    else:
        print(f"{variant}: written")


if __name__ == "__main__":
    main()
