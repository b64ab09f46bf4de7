"""How many drops a configuration needs under each initial-yaw design (``feeder bench-yaws``).

The orientation PMF of a configuration is a sample estimate: its error falls with the number of
drops, and the design of the initial yaws decides how fast. ``random`` draws them independently
(the paper); ``golden`` spreads every prefix evenly over the circle (:func:`feeder.sim.drops.initial_yaws`).
Over the panel of ``sim.bench.panel`` (shape specs, so the benchmark does not depend on the part
library), a reference of ``reference_drops`` independent drops is simulated with the first seed;
each design is simulated with the second seed for the largest drop level, and its first k drops
(k in ``drop_levels``) are compared with the reference: JS divergence (bits), W1 on the CDF
(degrees), CDF R², the same distances as ``feeder bench-sim``. Both designs are measured against
the same reference, whose own sampling error is in both distances alike.

Writes a CSV with one row per design × drop level × configuration and ``config == "mean"`` rows,
where ``random_drops_same_w1`` is the number of independent drops that reaches the design's mean
W1 (a power law fitted to the ``random`` mean rows, W1 = a·N^b, inverted): the drops a design saves.
The figure (``feeder figure yaw_sampling``) draws the mean distances against drops.
"""

from __future__ import annotations

import math
import sys
import time
from multiprocessing import get_context

import numpy as np

from feeder.errors import FeederError

DESIGNS = ("random", "golden")


def _run(job):
    """Worker: one (role, design, seed, panel entry) simulation → role, design, index, yaws, CPU seconds."""
    role, design, drops, seed, idx, entry, scene, preset, thickness = job
    from feeder.lane.fences import parse_location
    from feeder.parts.shapes import shape_part
    from feeder.sim.simulate import simulate

    shape, loc1, loc2 = entry
    geom = shape_part(shape, thickness)
    t0 = time.process_time()
    res = simulate(geom, parse_location(loc1), parse_location(loc2), drops, seed, scene, preset, yaw_sampling=design)
    return role, design, idx, res["final_yaw_deg"], time.process_time() - t0


def power_law(drops, values) -> tuple[float, float]:
    """Least-squares fit of values = a · drops^b on log axes → (a, b); NaN without two finite points."""
    x, y = np.log(np.asarray(drops, float)), np.asarray(values, float)
    ok = np.isfinite(x) & np.isfinite(y) & (y > 0)
    if ok.sum() < 2 or np.ptp(x[ok]) == 0:
        return math.nan, math.nan
    b, log_a = np.polyfit(x[ok], np.log(y[ok]), 1)
    return float(math.exp(log_a)), float(b)


def drops_for(value: float, a: float, b: float) -> float:
    """The drop count at which a · N^b equals ``value`` (NaN if the fit does not fall with N)."""
    if not (np.isfinite(value) and np.isfinite(a) and np.isfinite(b)) or value <= 0 or b >= 0:
        return math.nan
    return float((value / a) ** (1.0 / b))


def summarize(results, ref, panel, levels, labels_cfg):
    """Rows per design × level × configuration plus mean rows (see the module docstring)."""
    import pandas as pd

    from feeder.bench.accuracy import _metrics

    bins, sigma = int(labels_cfg["bins"]), float(labels_cfg["sigma_bins"])
    rows = []
    for design in DESIGNS:
        for k in levels:
            per = []
            for i, entry in enumerate(panel):
                yaws, cpu = results[(design, i)]
                js, w1, r2 = _metrics(yaws[:k], ref[i], bins, sigma)
                per.append(
                    dict(
                        design=design,
                        drops=k,
                        config="|".join(entry),
                        js=js,
                        w1_deg=w1,
                        r2_cdf=r2,
                        ms_per_drop=1e3 * cpu / len(yaws),
                        ok_rate=float(np.mean(np.isfinite(yaws[:k]))),
                    )
                )
            rows += per
            df = pd.DataFrame(per)
            rows.append(
                dict(
                    design=design,
                    drops=k,
                    config="mean",
                    js=df["js"].mean(),
                    w1_deg=df["w1_deg"].mean(),
                    r2_cdf=df["r2_cdf"].mean(),
                    ms_per_drop=df["ms_per_drop"].mean(),
                    ok_rate=df["ok_rate"].mean(),
                )
            )
    out = pd.DataFrame(rows)
    mean = out["config"] == "mean"
    rnd = out[mean & (out["design"] == "random")]
    a, b = power_law(rnd["drops"], rnd["w1_deg"])
    out["random_drops_same_w1"] = np.nan
    out.loc[mean, "random_drops_same_w1"] = [drops_for(v, a, b) for v in out.loc[mean, "w1_deg"]]
    out["drops_saved_factor"] = out["random_drops_same_w1"] / out["drops"]
    return out


def run_bench(scene, sim_cfg, labels_cfg, progress=False):
    presets, yb, panel_cfg = sim_cfg["presets"], sim_cfg["yaw_bench"], sim_cfg["bench"]
    panel = [tuple(e) for e in panel_cfg["panel"]]
    if yb["preset"] not in presets:
        raise FeederError(f"sim.yaw_bench.preset {yb['preset']!r} is not a preset")
    preset = dict(presets[yb["preset"]])
    seeds = [int(s) for s in yb["seeds"]]
    if len(seeds) != 2:
        raise FeederError("sim.yaw_bench.seeds must hold two seeds (reference, estimates)")
    levels = sorted({int(k) for k in yb["drop_levels"]})
    ref_drops, thickness = int(yb["reference_drops"]), float(panel_cfg["thickness"])
    if levels[-1] > ref_drops:
        raise FeederError("sim.yaw_bench.drop_levels must not exceed reference_drops")
    jobs = [("reference", "random", ref_drops, seeds[0], i, e, scene, preset, thickness) for i, e in enumerate(panel)]
    jobs += [
        ("estimate", d, levels[-1], seeds[1], i, e, scene, preset, thickness)
        for d in DESIGNS
        for i, e in enumerate(panel)
    ]
    ref, results = {}, {}
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(jobs), unit="run", file=sys.stderr)
    with get_context("fork").Pool(max(1, int(yb["workers"]))) as pool:  # references (longest) first
        for role, design, idx, yaws, cpu in pool.imap_unordered(_run, jobs):
            if role == "reference":
                ref[idx] = yaws
            else:
                results[(design, idx)] = (yaws, cpu)
            if bar is not None:
                bar.update(1)
    if bar is not None:
        bar.close()
    out = summarize(results, ref, panel, levels, labels_cfg)
    out.insert(3, "reference_drops", ref_drops)
    out.insert(4, "preset", yb["preset"])
    return out


def main(argv: list[str]) -> int:
    from feeder.bench.accuracy import bench_cli
    from feeder.io import write_csv

    out_csv, scene, sim_cfg, labels_cfg = bench_cli("feeder bench-yaws", __doc__, argv)
    if "yaw_bench" not in sim_cfg:
        raise FeederError("settings lack section sim.yaw_bench")
    df = run_bench(scene, sim_cfg, labels_cfg, progress=sys.stderr.isatty())
    write_csv(out_csv, df)
    for _, r in df[df["config"] == "mean"].iterrows():
        print(
            f"{r['design']:>7} {int(r['drops']):5d} drops: JS {r['js']:.4f}  W1 {r['w1_deg']:6.2f} deg  "
            f"R2 {r['r2_cdf']:.3f}  = {r['random_drops_same_w1']:.0f} random drops",
            file=sys.stderr,
        )
    return 0
