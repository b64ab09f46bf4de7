"""One configuration through the simulator, by any initial-yaw design (``feeder simulate``).

:func:`simulate` runs the drops of one part through one fence configuration
(:func:`feeder.sim.drops.run_drops`) for the drawn designs (``random``, ``golden``, ``grid``:
:func:`feeder.sim.drops.initial_yaws`) or the ``adaptive`` design, which chooses its initial yaws
as it goes (:func:`feeder.sim.adaptive.refine`), folded over the part's rotational symmetry
(:mod:`feeder.parts.symmetry`). The result is what :mod:`feeder.sim.record` writes (docs/data.md).
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
import time
from pathlib import Path

import numpy as np

from feeder.errors import FeederError
from feeder.lane.fences import Fence, config_id, parse_location
from feeder.lane.settings import load_settings
from feeder.parts.symmetry import check_order, rotational_order
from feeder.sim.adaptive import DEFAULT_MIN_WIDTH_DEG, DEFAULT_N0, DEFAULT_TOLERANCE_DEG, Design, refine
from feeder.sim.drops import STATUSES, YAW_SAMPLINGS, drop_seed, get_preset, initial_yaws, run_drops, run_each


def symmetry_order(geom, setting) -> int:
    """The rotational order an adaptive design may fold over: ``auto`` computes it from the
    part's outline (:func:`feeder.parts.symmetry.rotational_order`); a number is checked
    against the geometry (a part without that symmetry is refused)."""
    if setting == "auto":
        return rotational_order(geom.outline, holes=geom.holes)
    try:
        order = int(setting)
    except (TypeError, ValueError):
        raise FeederError(f"symmetry must be auto or a positive integer, got {setting!r}") from None
    if order < 1 or order != float(setting):
        raise FeederError(f"symmetry must be auto or a positive integer, got {setting!r}")
    if order > 1:
        check_order(geom.outline, order, holes=geom.holes)
    return order


def run_design(evaluate, seed: int, budget: int, adaptive: dict, order: int) -> Design:
    """The adaptive design: evenly spaced ``n0`` yaws over one symmetry period with a random
    offset from ``seed``, refined where the drop map jumps, at most ``budget`` simulations
    (:func:`feeder.sim.adaptive.refine`). ``adaptive``: ``n0``, ``tolerance_deg``,
    ``min_width_deg`` (``sim.adaptive``)."""
    period = 360.0 / order
    n0 = int(adaptive["n0"])
    if n0 < 2:
        raise FeederError(f"sim.adaptive.n0 must be at least 2, got {n0}")
    offset = float(np.random.default_rng(seed).uniform(0.0, period / n0))
    return refine(
        evaluate,
        n0=n0,
        tolerance_deg=float(adaptive["tolerance_deg"]),
        min_width_deg=float(adaptive["min_width_deg"]),
        budget=int(budget),
        offset_deg=offset,
        period_deg=period,
        stop_if_none_ok=bool(adaptive.get("stop_if_none_ok", False)),
    )


def design_record(design: Design, order: int) -> tuple[dict, dict]:
    """What a simulation file keeps of an adaptive design: arrays and a JSON-able summary."""
    arrays = {
        "unresolved_deg": np.asarray(design.unresolved, dtype=np.float64).reshape(-1, 2),
        "unchecked_deg": np.asarray(design.unchecked, dtype=np.float64).reshape(-1, 2),
        "unresolved_share": np.float64(design.unresolved_share),
    }
    summary = {
        "symmetry_order": int(order),
        "period_deg": design.period_deg,
        "offset_deg": design.offset_deg,
        "tolerance_deg": design.tolerance_deg,
        "min_width_deg": design.min_width_deg,
        "max_width_deg": design.max_width_deg,
        "band_gap_deg": design.band_gap_deg,
        "edge_check_deg": design.edge_check_deg,
        "evaluations": int(design.evaluations),
        "calls": int(design.calls),
        "unresolved_share": float(design.unresolved_share),
    }
    return arrays, summary


def simulate_adaptive(run, geom, seed: int, budget: int, preset: dict, adaptive: dict | None):
    """The adaptive design's drops: ``run(yaws)`` simulates one batch (a round of refinement) and
    returns :func:`run_drops`'s result. Returns the sorted initial yaws, the drops' results, the
    design arrays and the design summary (:func:`design_record`)."""
    if adaptive is None:
        raise FeederError("the adaptive design needs its settings (sim.adaptive)")
    if int(preset["lanes"]) != 1:
        raise FeederError(f"the adaptive design needs lanes: 1 (one part per world), the preset has {preset['lanes']}")
    order = symmetry_order(geom, adaptive.get("symmetry", "auto"))
    diags = []

    def evaluate(yaws):
        res = run(yaws)
        diags.append(res["diag"])
        return res["final_yaw_deg"], res["status"]

    stop = adaptive.get("stop", "budget")
    estimate = None
    if stop == "budget":
        design = run_design(evaluate, seed, budget, adaptive, order)
    elif stop == "target":
        from feeder.circular import LABEL_BINS, LABEL_SIGMA_BINS
        from feeder.sim.errest import targeted

        design, estimate, _ = targeted(evaluate, seed, adaptive, order, LABEL_BINS, LABEL_SIGMA_BINS)
    else:
        raise FeederError(f"sim.adaptive.stop must be budget or target, got {stop!r}")
    out = {"final_yaw_deg": design.final, "status": design.status, "diag": diags}
    arrays, summary = design_record(design, order)
    summary |= {"n0": int(adaptive["n0"]), "symmetry": adaptive.get("symmetry", "auto"), "stop": stop}
    if adaptive.get("stop_if_none_ok"):
        summary["stop_if_none_ok"] = True
    if estimate is not None:
        summary |= {"est_sup_cdf": estimate.sup_cdf, "est_circular_w1_deg": estimate.circular_w1_deg}
    return design.yaws, out, arrays, summary


def run_yaw_design(
    geom, loc1, loc2, drops, seed, scene, preset, progress, probe_x, check_fences, prune, yaw_sampling, adaptive
):
    """The drops of one configuration by its initial-yaw design (``seed``: the configuration's
    own, :func:`feeder.sim.drops.drop_seed`): the initial yaws, :func:`run_drops`'s result, and
    for ``adaptive`` the design's arrays and summary (else empty and None)."""
    extra, design_meta = {}, None
    if yaw_sampling == "adaptive":
        run = functools.partial(
            run_each,
            geom,
            loc1,
            loc2,
            scene=scene,
            preset=preset,
            probe_x=probe_x,
            check_fences=check_fences,
            prune=prune,
        )
        y0, out, extra, design_meta = simulate_adaptive(run, geom, seed, int(drops), preset, adaptive)
    else:
        y0 = initial_yaws(seed, int(drops), yaw_sampling)
        # a sampled map (grid) needs each drop's outcome to depend on its yaw alone: a world each
        out = (run_each if yaw_sampling == "grid" else functools.partial(run_drops, progress=progress))(
            geom,
            loc1,
            loc2,
            y0,
            scene,
            preset,
            probe_x=probe_x,
            check_fences=check_fences,
            prune=prune,
        )
    return y0, out, extra, design_meta


def simulate(
    geom,
    loc1: Fence,
    loc2: Fence,
    drops: int,
    seed: int,
    scene: dict,
    preset: dict,
    preset_name: str = "custom",
    progress: bool = False,
    probe_x: float | None = None,
    check_fences: bool = False,
    prune: bool = True,
    yaw_sampling: str = "random",
    adaptive: dict | None = None,
) -> dict:
    """One configuration: the npz payload (docs/data.md) plus ``diag`` (not written).

    ``drops`` is the number of simulations; for ``adaptive`` it is the budget (at most that many),
    and ``adaptive`` holds the design's settings (``sim.adaptive``: n0, tolerance_deg,
    min_width_deg, symmetry). The sampled maps (``grid``, ``adaptive``) run every drop in a world of
    its own (:func:`feeder.sim.drops.run_each`), and the adaptive design needs ``lanes: 1``: only
    then is a drop's outcome a function of its initial yaw alone.
    """
    if int(drops) != drops or drops < 1:
        raise FeederError(f"drops must be a positive integer, got {drops!r}")
    if yaw_sampling not in YAW_SAMPLINGS:
        raise FeederError(f"yaw sampling must be one of {', '.join(YAW_SAMPLINGS)}, got {yaw_sampling!r}")
    cfg = config_id(loc1, loc2)
    s = drop_seed(geom.part_id, cfg, seed)
    t0, c0 = time.perf_counter(), time.process_time()
    y0, out, extra, design_meta = run_yaw_design(
        geom, loc1, loc2, drops, s, scene, preset, progress, probe_x, check_fences, prune, yaw_sampling, adaptive
    )
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    meta = {
        "part": geom.part_id,
        "loc1": loc1.spec,
        "loc2": loc2.spec,
        "config_id": cfg,
        "preset": preset_name,
        "seed": int(seed),
        "drops": int(drops),
        "yaw_sampling": yaw_sampling,
        "simulations": int(len(y0)),
        "settings": {"scene": scene, "preset": preset},
        "status_counts": {k: int(np.sum(out["status"] == k)) for k in STATUSES},
    }
    if design_meta is not None:
        meta["design"] = design_meta
    return {
        "final_yaw_deg": np.asarray(out["final_yaw_deg"], dtype=np.float64),
        "initial_yaw_deg": y0,
        "status": np.asarray(out["status"]).astype(str),
        "wall_s": np.float64(wall),
        "cpu_s": np.float64(cpu),
        "meta": json.dumps(meta, sort_keys=True),
        "diag": out["diag"],
        **extra,
    }


# --------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------
def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="feeder simulate", description=__doc__.splitlines()[0])
    parser.add_argument("--part", required=True, help="parts/<id>.stl")
    parser.add_argument("--loc1", required=True, help="none | straight:ANGLE | curved:ANGLE (downstream)")
    parser.add_argument("--loc2", required=True, help="none | straight:ANGLE | curved:ANGLE (upstream)")
    parser.add_argument(
        "--drops",
        type=int,
        required=True,
        help="simulations; for --yaw-sampling adaptive the budget (at most this many)",
    )
    parser.add_argument("--seed", type=int, default=0, help="base seed")
    parser.add_argument(
        "--units",
        default="auto",
        choices=("auto", "m", "mm"),
        help="units of the part file; auto: millimetres if the part would be wider than 1 m, else metres",
    )
    parser.add_argument("--preset", default="fast")
    parser.add_argument(
        "--yaw-sampling",
        default="random",
        choices=YAW_SAMPLINGS,
        help="initial yaws: random (independent, the paper), golden (even prefixes), grid "
        "(evenly spaced, random offset) or adaptive (refined where the outcome jumps)",
    )
    adaptive = parser.add_argument_group("adaptive design (--yaw-sampling adaptive; sim.adaptive)")
    adaptive.add_argument("--n0", type=int, default=DEFAULT_N0, help="evenly spaced start yaws per period")
    adaptive.add_argument(
        "--tolerance-deg",
        type=float,
        default=DEFAULT_TOLERANCE_DEG,
        help="final yaws further apart than this mark a jump to bisect",
    )
    adaptive.add_argument(
        "--min-width-deg", type=float, default=DEFAULT_MIN_WIDTH_DEG, help="intervals are not bisected below this width"
    )
    adaptive.add_argument(
        "--symmetry", default="auto", help="rotational order to fold over: auto (from the outline) or N (checked)"
    )
    adaptive.add_argument(
        "--stop-if-none-ok",
        default="false",
        help="true: stop after the start grid when none of its drops ends ok (the configuration carries no "
        "orientation label; sim.adaptive.stop_if_none_ok) (default: false)",
    )
    adaptive.add_argument(
        "--stop",
        default="budget",
        help="budget: at most --drops simulations; target: stop once the error estimate is within the targets "
        "(sim.adaptive_stop, sim.adaptive_target; feeder.sim.errest)",
    )
    target = parser.add_argument_group("targeted design (--stop target; sim.adaptive_target)")
    from feeder.sim.errest import DEFAULT_TARGET

    for key, default in DEFAULT_TARGET.items():
        name, kind = key.replace("_", "-"), type(default)
        target.add_argument(f"--{name}", type=kind, default=default, help=f"sim.adaptive_target.{key}")
    parser.add_argument("--settings", default=None, help="JSON {scene, presets}; default config/config.yaml")
    parser.add_argument("--out", required=True, help="output .npz")
    return parser


def _flag(value: str, name: str) -> bool:
    """``true`` / ``false`` (any case) as a bool; anything else a one-line FeederError."""
    text = str(value).strip().lower()
    if text not in ("true", "false"):
        raise FeederError(f"{name} must be true or false, got {value!r}")
    return text == "true"


def main(argv: list[str]) -> int:
    args = _parser().parse_args(argv)

    loc1, loc2 = parse_location(args.loc1), parse_location(args.loc2)
    if args.drops < 1:
        raise FeederError(f"--drops must be positive, got {args.drops}")
    if Path(args.out).suffix.lower() != ".npz":  # what it writes, whatever the name says
        raise FeederError(f"--out {args.out}: feeder simulate writes a NumPy archive of the drops; name it .npz")
    scene, presets = load_settings(args.settings)
    preset = get_preset(presets, args.preset)
    from feeder.parts.geometry import load_part_units

    path = Path(args.part)
    if not path.is_file():
        raise FeederError(f"part file {path} not found")
    geom, unit = load_part_units(path, args.units)
    try:
        design = {
            "n0": args.n0,
            "tolerance_deg": args.tolerance_deg,
            "min_width_deg": args.min_width_deg,
            "symmetry": args.symmetry,
            "stop_if_none_ok": _flag(args.stop_if_none_ok, "--stop-if-none-ok"),
            "stop": args.stop,
            "target": {
                "target_w1_deg": args.target_w1_deg,
                "target_sup_cdf": args.target_sup_cdf,
                "min_budget": args.min_budget,
                "cap": args.cap,
                "audits": args.audits,
                "step": args.step,
                "confidence": args.confidence,
            },
        }
        res = simulate(
            geom,
            loc1,
            loc2,
            args.drops,
            args.seed,
            scene,
            preset,
            args.preset,
            progress=sys.stderr.isatty(),
            yaw_sampling=args.yaw_sampling,
            adaptive=design,
        )
    except KeyError as err:
        raise FeederError(f"scene settings lack key {err}") from None
    from feeder.sim.record import write_sim

    write_sim(args.out, res)
    if args.units == "auto" and unit != "m":  # say so when auto did not read metres (after a failure: one line)
        print(f"{path}: read in {unit} (--units auto)", file=sys.stderr)
    counts = json.loads(res["meta"])["status_counts"]
    print(
        f"{geom.part_id} {config_id(loc1, loc2)}: {len(res['status'])} drops in {float(res['wall_s']):.1f} s; "
        + ", ".join(f"{k} {n}" for k, n in counts.items() if n),
        file=sys.stderr,
    )
    return 0
