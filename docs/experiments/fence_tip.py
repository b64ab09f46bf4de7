"""Does the simulator's square fence tip push with the face's normal past the tip? (issue #39)

``docs/experiments/analytic_dropwise.py`` finds the analytic model furthest from the simulator on
one straight fence at steep angles (13 % of the initial yaws agree at 60 degrees, 83 % at 25),
where the simulated part turns further past the tip than the quasi-static exit turn
(``feeder.mechanics.exitturn``). A fence is a box ``scene.fences.thickness`` thick; where a
part's edge pivots about the box's corner at the tip, the physical contact normal is that edge's
normal, whatever the fence's thickness. This script tests whether Bullet agrees, in two parts:

1. **One drop traced** (rect-a3 on ``straight:60``, initial yaw ``TRACE_YAW``): at every state
   check past the tip, the part's yaw and every fence contact's position, normal direction and
   normal force, with the square tip of the study and with a round one.
2. **Paired sweep.** Every configuration of the study with one straight fence at ``--min-angle``
   degrees or more (Location 1, Location 2 empty), ``--others`` more such single-fence
   configurations (any type and angle) and ``--two-fence`` two-fence configurations with a
   straight fence that steep (both chosen by sha256 of their names). Each is simulated three
   ways: the study's scene (square tip, 10 mm); the same with a round tip (a vertical cylinder of
   the fence's half thickness capping its free end, so the face runs smoothly into it: the box is
   unchanged, the tip reaches half a thickness further); and a square tip on a fence ``THIN_M``
   thick. The same preset, an evenly spaced grid of ``DROPS`` initial yaws with one offset (base
   seed ``SEED``), so the runs are paired drop by drop. Per drop it records the final yaws and
   status and the analytic model's yaw (``analytic_dropwise.analytic_final``). It prints, per
   group, the share of drops in the same basin as the study's (both ok and within ``AGREE_DEG``
   modulo the symmetry period), the median |change of final yaw| over those, the share of each
   run that agrees with the analytic model, and circular W1 between the runs' PMFs and to the
   analytic PMF.

The round tip is the setting ``scene.fences.tip: round`` (``feeder.lane.geometry.FenceGeom.tip_cap``);
the study's scene leaves it out (square).

    python docs/experiments/fence_tip.py SIM_DIR PARTS_DIR OUT_CSV [--min-angle 45] [--others 24] \
        [--two-fence 24]

SIM_DIR is a run's ``results/sim`` (which configurations exist). Simulation files go to
``results/bench/fence_tip/sim/`` and are reused while their request is unchanged; raw rows (one per
drop and variant) go to OUT_CSV, the trace to OUT_CSV with ``_trace`` before the suffix.
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads: OpenBLAS's AVX2 kernel (feeder/__init__.py)

# isort: on
import argparse
import copy
import hashlib
import json
import math
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from analytic_dropwise import AGREE_DEG, analytic_final  # noqa: E402

import feeder.sim.drops as drops  # noqa: E402
from feeder.circular import LABEL_BINS, LABEL_SIGMA_BINS, wrapped_gaussian_smooth  # noqa: E402
from feeder.config import load_study_config  # noqa: E402
from feeder.io import write_csv, write_npz  # noqa: E402
from feeder.labels.metrics import circular_w1  # noqa: E402
from feeder.lane.fences import parse_config_id, parse_location  # noqa: E402
from feeder.mechanics.fence import fence_models, fence_mu  # noqa: E402
from feeder.mechanics.hull import as_geometry  # noqa: E402
from feeder.mechanics.pmf import analytic_pmf, bin_masses  # noqa: E402
from feeder.parts.geometry import load_part_units  # noqa: E402
from feeder.sim.drops import get_preset  # noqa: E402
from feeder.sim.simulate import simulate, symmetry_order  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SIM_OUT = ROOT / "results" / "bench" / "fence_tip" / "sim"
THIN_M = 0.002  # the thin fence (metres); the study's is scene.fences.thickness
DROPS = 16  # evenly spaced initial yaws per configuration and variant
SEED = 0  # base seed: the grid's offset, the same for every variant
RESAMPLES = 10_000  # bootstrap resamples over configurations
BOOT_SEED = 0
TRACE = ("rect-a3", "straight:60", 141.1)  # part, fence, initial yaw of the traced drop


def variant_scene(scene: dict, variant: str) -> dict:
    """The scene of a variant: ``square`` (the study's), ``round`` (``scene.fences.tip: round``),
    ``thin`` (a square tip ``THIN_M`` thick)."""
    out = copy.deepcopy(scene)
    if variant == "thin":
        out["fences"]["thickness"] = THIN_M
    if variant == "round":
        out["fences"]["tip"] = "round"
    return out


def one(job: tuple) -> list[dict]:
    part, config_id, variant, settings, parts_dir = job
    scene = variant_scene(settings["scene"], variant)
    sim = settings["sim"]
    preset = get_preset(sim["presets"], sim["preset"])
    request = json.dumps(
        {
            "part": part,
            "config": config_id,
            "variant": variant,
            "drops": DROPS,
            "seed": SEED,
            "scene": scene,
            "preset": preset,
        },
        sort_keys=True,
    )
    path = SIM_OUT / part / f"{config_id}__{variant}.npz"
    geom, _ = load_part_units(Path(parts_dir) / f"{part}.stl", str(settings["parts"]["units"]))
    keys = ("initial_yaw_deg", "final_yaw_deg", "status", "cpu_s")
    res = None
    if path.is_file():
        with np.load(path, allow_pickle=False) as z:
            if str(z["request"]) == request:
                res = {k: z[k] for k in keys}
    if res is None:
        loc1, loc2 = parse_config_id(config_id)
        out = simulate(geom, loc1, loc2, DROPS, SEED, scene, preset, sim["preset"], yaw_sampling="grid")
        res = {k: out[k] for k in keys}
        path.parent.mkdir(parents=True, exist_ok=True)
        write_npz(path, request=np.array(request), **res)
    loc1, loc2 = parse_config_id(config_id)
    study = settings["scene"]
    try:
        ana, _ = analytic_final(
            as_geometry(geom), fence_models(loc1, loc2, study), res["initial_yaw_deg"], fence_mu(study), {}
        )
        rolls = False
    except ValueError:  # a fence rolls the part: the analytic model gives no yaw per drop
        ana, rolls = np.full(DROPS, np.nan), True
    period = 360.0 / symmetry_order(geom, "auto")
    return [
        {
            "part": part,
            "config_id": config_id,
            "variant": variant,
            "period": period,
            "drop": i,
            "initial_yaw_deg": float(res["initial_yaw_deg"][i]),
            "status": str(res["status"][i]),
            "final_yaw_deg": float(res["final_yaw_deg"][i]),
            "analytic_yaw_deg": float(ana[i]),
            "rolls": rolls,
            "cpu_s": float(res["cpu_s"]) / DROPS,
        }
        for i in range(DROPS)
    ]


def trace(settings: dict, parts_dir: Path) -> pd.DataFrame:
    """Part 1: the traced drop's fence contacts, square and round tip."""
    part, loc1, yaw0 = TRACE
    geom, _ = load_part_units(Path(parts_dir) / f"{part}.stl", str(settings["parts"]["units"]))
    rows: list[dict] = []
    check = drops.check_lane

    def recording(world, lane, ln, t, lim, ways, probes):
        s = drops.part_state(world, lane, ln.body, t - ln.t0)
        if s is not None:
            for c in world.pb.getContactPoints(bodyA=ln.body, physicsClientId=world.cid):
                if c[2] in world.belts or abs(c[7][2]) > 0.5:  # the belt, not a fence
                    continue
                rows.append(
                    {
                        "tip": tip,
                        "t_s": s.elapsed,
                        "x": s.x,
                        "y": s.y,
                        "yaw_deg": s.yaw_deg,
                        "contact_x": c[6][0],
                        "contact_y": c[6][1],
                        "normal_deg": math.degrees(math.atan2(c[7][1], c[7][0])),
                        "normal_force": c[9],
                    }
                )
        return check(world, lane, ln, t, lim, ways, probes)

    sim = settings["sim"]
    preset = get_preset(sim["presets"], sim["preset"])
    drops.check_lane = recording
    try:
        for tip in ("square", "round"):
            out = drops.run_drops(
                geom,
                parse_location(loc1),
                parse_location("none"),
                np.array([yaw0]),
                variant_scene(settings["scene"], tip),
                preset,
            )
            print(
                f"traced {part} {loc1} from {yaw0} deg, {tip} tip: ends at {out['final_yaw_deg'][0]:.1f} deg "
                f"({out['status'][0]})"
            )
    finally:
        drops.check_lane = check
    return pd.DataFrame(rows)


def same(a, b, period) -> np.ndarray:
    return np.abs((np.asarray(a) - np.asarray(b) + period / 2) % period - period / 2) < AGREE_DEG


def summarise(raw: pd.DataFrame) -> pd.DataFrame:
    idx = ["part", "config_id", "drop"]
    base = raw[raw.variant == "square"].set_index(idx)
    out = []
    for variant, g in raw.groupby("variant"):
        g = g.set_index(idx).reindex(base.index)
        if not np.allclose(g.initial_yaw_deg, base.initial_yaw_deg):
            sys.exit(f"{variant} does not share the study's initial yaws: not paired")
        ok = (g.status == "ok") & (base.status == "ok")
        sb = ok & same(g.final_yaw_deg, base.final_yaw_deg, base.period)
        d = np.abs((g.final_yaw_deg - base.final_yaw_deg + base.period / 2) % base.period - base.period / 2)
        agrees = (
            (g.status == "ok") & g.analytic_yaw_deg.notna() & same(g.final_yaw_deg, g.analytic_yaw_deg, base.period)
        )
        agrees = agrees.astype(float).where(~g.rolls.astype(bool))  # no yaw per drop to agree with
        out.append(
            pd.DataFrame(
                {
                    "variant": variant,
                    "same_basin": sb,
                    "abs_dyaw": d.where(sb),
                    "agrees_analytic": agrees,
                    "not_ok": g.status != "ok",
                },
                index=base.index,
            )
        )
    return pd.concat(out)


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sim_dir", type=Path)
    ap.add_argument("parts_dir", type=Path)
    ap.add_argument("out_csv", type=Path)
    ap.add_argument("--min-angle", type=float, default=45.0)
    ap.add_argument("--others", type=int, default=24)
    ap.add_argument("--two-fence", type=int, default=24)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)
    config = load_study_config(root=ROOT)
    settings = {k: config[k] for k in ("scene", "sim", "parts")}
    tr = trace(settings, args.parts_dir)
    write_csv(args.out_csv.with_name(args.out_csv.stem + "_trace" + args.out_csv.suffix), tr)

    def steep_straight(token: str) -> bool:
        kind = token.rstrip("0123456789.")
        return kind == "straight" and float(token[len(kind) :]) >= args.min_angle

    def group(cid: str) -> str:
        """``steep one``: one straight fence at Location 1 at min-angle or more; ``other one``: any
        other fence at Location 1 alone; ``steep two``: two fences, one of them straight at min-angle
        or more; ``other``: the rest (two shallow fences, a fence at Location 2 alone)."""
        loc1, loc2 = cid.split("_")
        if loc2 == "none" and loc1 != "none":
            return f"{'steep' if steep_straight(loc1) else 'other'} one"
        if "none" not in (loc1, loc2) and (steep_straight(loc1) or steep_straight(loc2)):
            return "steep two"
        return "other"

    def by_hash(configs):
        return sorted(configs, key=lambda c: hashlib.sha256(f"{c[0]}:{c[1]}".encode()).hexdigest())

    every = sorted((p.parent.name, p.stem) for p in args.sim_dir.glob("*/*.npz"))
    chosen = [c for c in every if group(c[1]) == "steep one"]
    chosen += by_hash(c for c in every if group(c[1]) == "other one")[: args.others]
    chosen += by_hash(c for c in every if group(c[1]) == "steep two")[: args.two_fence]
    counts = pd.Series([group(c[1]) for c in chosen]).value_counts().to_dict()
    print(f"{len(chosen)} configurations {counts}, 3 variants", file=sys.stderr)
    jobs = [(part, cid, v, settings, args.parts_dir) for part, cid in chosen for v in ("square", "round", "thin")]
    rows = []
    with ProcessPoolExecutor(args.workers) as pool:
        for k, out in enumerate(pool.map(one, jobs), 1):
            rows.extend(out)
            if k % 15 == 0:
                print(f"{k}/{len(jobs)}", file=sys.stderr, flush=True)
    raw = pd.DataFrame(rows)
    write_csv(args.out_csv, raw)
    flags = summarise(raw)
    flags["group"] = [group(c) for c in flags.index.get_level_values("config_id")]
    table = flags.groupby(["group", "variant"]).agg(
        configs=("same_basin", lambda s: s.index.droplevel("drop").nunique()),
        same_basin_as_study=("same_basin", "mean"),
        median_abs_dyaw=("abs_dyaw", "median"),
        agrees_analytic=("agrees_analytic", "mean"),
        not_ok=("not_ok", "mean"),
    )
    print(table.round(3).to_string())
    w1 = pmf_scores(raw, args.parts_dir, settings["scene"], str(settings["parts"]["units"]))
    write_csv(args.out_csv.with_name(args.out_csv.stem + "_pmf" + args.out_csv.suffix), w1)
    piv = w1.pivot_table(index=["part", "config_id"], columns="variant", values="analytic_cw1_deg")
    piv["group"] = [group(c) for c in piv.index.get_level_values("config_id")]
    print("circular W1 (deg) of the analytic PMF to each run's 16-drop PMF, mean over configurations:")
    print(piv.groupby("group")[["square", "round", "thin"]].mean().round(2).to_string())
    between = w1[w1.variant != "square"].pivot_table(
        index=["part", "config_id"], columns="variant", values="to_square_cw1_deg"
    )
    between["group"] = [group(c) for c in between.index.get_level_values("config_id")]
    print("circular W1 (deg) of each run's PMF to the study's (square) one:")
    print(between.groupby("group")[["round", "thin"]].mean().round(2).to_string())
    for name in ("steep one", "steep two"):
        sel = piv[piv.group == name]
        d = (sel["round"] - sel["square"]).dropna().to_numpy()
        if d.size:
            lo, hi = paired_interval(d)
            print(
                f"{name}, round minus square, analytic PMF's W1: {d.mean():+.2f} [{lo:+.2f}, {hi:+.2f}] deg, {d.size}"
            )
        per = (
            flags[flags.group == name]
            .groupby(["variant", "part", "config_id"])
            .agg(same=("same_basin", "mean"), agrees=("agrees_analytic", "mean"))
        )
        if per.empty:
            continue
        for variant in ("round", "thin"):
            d = (per.loc[variant].agrees - per.loc["square"].agrees).dropna().to_numpy()
            lo, hi = paired_interval(d)
            same_lo, same_hi = paired_interval(per.loc[variant].same.to_numpy())
            print(
                f"{name}, {variant} minus square: agreement with the analytic model {d.mean():+.3f} "
                f"[{lo:+.3f}, {hi:+.3f}] over {d.size} configurations; same basin as the study "
                f"{per.loc[variant].same.mean():.3f} [{same_lo:.3f}, {same_hi:.3f}]"
            )
    return 0


def run_pmf(yaws: np.ndarray, ok: np.ndarray) -> np.ndarray | None:
    """A run's PMF over ``LABEL_BINS`` bins of its ok drops (equal weights: an even grid), smoothed
    as the labels are; None when no drop ended ok."""
    if not ok.any():
        return None
    hist = bin_masses(yaws[ok], np.full(int(ok.sum()), 1.0 / ok.sum()), LABEL_BINS)
    return wrapped_gaussian_smooth(hist, LABEL_SIGMA_BINS)


def pmf_scores(raw: pd.DataFrame, parts_dir: Path, scene: dict, units: str) -> pd.DataFrame:
    """Per configuration and run: circular W1 of the analytic PMF (part frame, the study's scene)
    to the run's PMF, and of the run's PMF to the study's (square) run's."""
    rows = []
    for (part, config_id), g in raw.groupby(["part", "config_id"]):
        geom, _ = load_part_units(Path(parts_dir) / f"{part}.stl", units)
        loc1, loc2 = parse_config_id(config_id)
        ana = np.cumsum(analytic_pmf(as_geometry(geom), loc1, loc2, scene))
        pmfs = {v: run_pmf(r.final_yaw_deg.to_numpy(), (r.status == "ok").to_numpy()) for v, r in g.groupby("variant")}
        for variant, pmf in pmfs.items():
            if pmf is None or pmfs["square"] is None:
                continue
            cdf = np.cumsum(pmf)
            rows.append(
                {
                    "part": part,
                    "config_id": config_id,
                    "variant": variant,
                    "analytic_cw1_deg": float(circular_w1(ana, cdf)),
                    "to_square_cw1_deg": float(circular_w1(np.cumsum(pmfs["square"]), cdf)),
                }
            )
    return pd.DataFrame(rows)


def paired_interval(values: np.ndarray, resamples: int = RESAMPLES) -> tuple[float, float]:
    """95 % bootstrap interval of the mean of per-configuration values (seeded)."""
    rng = np.random.default_rng(BOOT_SEED)
    means = values[rng.integers(0, values.size, (resamples, values.size))].mean(axis=1)
    return float(np.quantile(means, 0.025)), float(np.quantile(means, 0.975))


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
