"""Accuracy against time of the simulation settings (``feeder bench-sim``).

Over a fixed panel of part × fence configurations (``sim.bench.panel``: shape specs from
:mod:`feeder.parts.shapes`, so the benchmark does not depend on the part library), the reference
preset (``faithful``) is run with two base seeds; the two runs' distance is the *noise floor*
(what sampling alone gives at this drop count). Each setting of ``sim.bench.sweep`` (overrides of
a base preset: time step, substeps, solver iterations, lanes, shortcuts) runs with the second
seed and is compared with the reference's first seed — so, like the floor, the comparison holds
two independent samples and a setting without bias lands at the floor. Drops per configuration
are swept by using the first k drops (``sim.bench.drop_levels``) of every run.

Distances per configuration (PMFs and CDFs as in :mod:`feeder.labels.metrics`, ok drops only): JS
divergence (bits), W1 on the CDF (degrees) and CDF R² (reference as truth); CPU milliseconds per
drop from the worker's process time. Writes a CSV (one row per setting × drop level × configuration
plus ``config = mean`` aggregate rows with the noise floor and the speed-up over the reference).
``within_floor`` on a mean row is a paired permutation test (:func:`paired_excess`): the setting's
second-seed run and the reference's second-seed run start every drop from the same initial yaw,
so the test asks whether the setting is farther from the reference's first seed than the
reference's own second seed is, beyond what swapping drop pairs explains (JS and W1, each at the
level ``1 - boot_quantile``). ``below_two_seed_floor`` keeps the plain comparison of the two panel
means, which even a physically identical rerun of the reference fails about half the time.
The Pareto plot (mean JS and W1 against CPU ms per drop, log axes, floor as a band) is drawn from
that CSV by ``feeder figure sim_accuracy_vs_time`` (:mod:`feeder.figures.sim_accuracy_vs_time`).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from multiprocessing import get_context

import numpy as np

from feeder.errors import FeederError


def _run(job):
    """Worker: one (setting, seed, panel entry) simulation → yaws, statuses, CPU seconds."""
    name, preset, seed, idx, entry, scene, thickness = job
    from feeder.lane.fences import parse_location
    from feeder.parts.shapes import shape_part
    from feeder.sim.simulate import simulate

    shape, loc1, loc2 = entry
    geom = shape_part(shape, thickness)
    t0 = time.process_time()
    res = simulate(
        geom,
        parse_location(loc1),
        parse_location(loc2),
        preset["drops"],
        seed,
        scene,
        {k: v for k, v in preset.items() if k != "drops"},
        name,
    )
    cpu = time.process_time() - t0
    return name, seed, idx, res["final_yaw_deg"], res["status"], cpu


def _metrics(yaws_a, yaws_b, bins, sigma):
    """JS, W1, CDF R² of sample a against sample b (b is the truth); NaN if either has no ok drop."""
    from feeder.labels import metrics as labels

    a, b = yaws_a[np.isfinite(yaws_a)], yaws_b[np.isfinite(yaws_b)]
    if a.size == 0 or b.size == 0:
        return np.nan, np.nan, np.nan
    pa, pb = labels.pmf_from_yaws(a, bins, sigma), labels.pmf_from_yaws(b, bins, sigma)
    ca, cb = labels.cdf(pa), labels.cdf(pb)
    return (float(labels.js_divergence(pa, pb)), float(labels.w1(ca, cb)), float(labels.r2_cdf(cb, ca)))


def bootstrap_js_floor(
    sample_a, sample_b, n: int, bins: int, sigma: float, resamples: int, quantile: float, seed: int
) -> float:
    """Bootstrap noise floor of the JS divergence between two samples of ``n`` drops.

    The ok yaws of two runs of the same process (e.g. two seeds) are pooled; pairs of samples of
    ``n`` drawn with replacement from the pool give the JS divergence expected from sampling alone;
    the ``quantile`` of ``resamples`` such values is returned (NaN when neither run has an ok drop,
    e.g. a fence that jams every part: the configuration then has no distribution to compare).
    Unlike a single two-seed value it also covers near-discrete outcomes (sub-degree peaks), where
    two seeds differ by peak weights only while any change of the numerics reshuffles drops within
    a peak.
    """
    from feeder.labels import metrics as labels

    pool = np.concatenate([np.asarray(sample_a, float), np.asarray(sample_b, float)])
    pool = pool[np.isfinite(pool)]
    if pool.size == 0:
        return float("nan")
    rng = np.random.default_rng(seed)
    idx_a = rng.integers(0, pool.size, size=(resamples, n))
    idx_b = rng.integers(0, pool.size, size=(resamples, n))
    pa = np.stack([labels.pmf_from_yaws(pool[i], bins, sigma) for i in idx_a])
    pb = np.stack([labels.pmf_from_yaws(pool[i], bins, sigma) for i in idx_b])
    return float(np.quantile(labels.js_divergence(pa, pb), quantile))


def paired_excess(triples, bins: int, sigma: float, resamples: int, seed: int) -> dict:
    """Is a setting farther from the reference than the reference's own second seed? (paired test)

    ``triples`` holds one ``(a, b, ref)`` per configuration: ``a`` the setting's final yaws and ``b``
    the reference's second-seed yaws, drop ``i`` of both started from the same initial yaw (NaN for
    a drop that is not ok), and ``ref`` the reference's first seed. The observed excess is the mean
    over configurations of ``d(a, ref) - d(b, ref)``. If the setting simulates the same process as
    the reference, ``a_i`` and ``b_i`` are exchangeable, so each resample swaps a random half of the
    pairs and recomputes the excess. Returns ``{"js": (excess, p), "w1": (excess, p)}`` with
    ``p = (1 + #{resampled excess >= observed}) / (1 + resamples)``: a small ``p`` means the setting
    is farther than sampling explains. A configuration without ok drops is left out (NaN mean).
    """
    from feeder.labels import metrics as labels

    def dists(x, ref_pmf, ref_cdf):
        x = x[np.isfinite(x)]
        if x.size == 0 or ref_pmf is None:
            return np.nan, np.nan
        px = labels.pmf_from_yaws(x, bins, sigma)
        return float(labels.js_divergence(px, ref_pmf)), float(labels.w1(labels.cdf(px), ref_cdf))

    rng = np.random.default_rng(seed)
    triples = [(np.asarray(a, float), np.asarray(b, float), ref) for a, b, ref in triples]
    refs = []
    for a, b, ref in triples:
        if len(a) != len(b):
            raise FeederError(f"paired_excess: paired samples differ in length ({len(a)} vs {len(b)})")
        r = np.asarray(ref, float)
        r = r[np.isfinite(r)]
        pr = labels.pmf_from_yaws(r, bins, sigma) if r.size else None
        refs.append((pr, None if pr is None else labels.cdf(pr)))

    def excess(swaps):
        d = []
        for (a, b, _), (pr, cr), sw in zip(triples, refs, swaps):
            a2, b2 = np.where(sw, b, a), np.where(sw, a, b)
            d.append(np.subtract(dists(a2, pr, cr), dists(b2, pr, cr)))
        return np.nanmean(np.array(d), axis=0) if d else np.array([np.nan, np.nan])

    observed = excess([np.zeros(len(a), bool) for a, _, _ in triples])
    null = np.array([excess([rng.random(len(a)) < 0.5 for a, _, _ in triples]) for _ in range(int(resamples))])
    p = (1.0 + np.sum(null >= observed - 1e-12, axis=0)) / (1.0 + int(resamples))
    return {"js": (float(observed[0]), float(p[0])), "w1": (float(observed[1]), float(p[1]))}


def resolve_setting(presets: dict, setting: dict) -> dict:
    """A sweep entry as a preset: its base preset with the entry's overrides (``scene`` excluded)."""
    base = setting.get("base", "fast")
    if base not in presets:
        raise FeederError(f"bench setting {setting.get('name')!r}: unknown base preset {base!r}")
    out = dict(presets[base])
    out.update({k: v for k, v in setting.items() if k not in ("name", "base", "scene")})
    return out


def merge_scene(scene: dict, change: dict | None) -> dict:
    """``scene`` with the nested values of ``change`` replaced (a sweep entry's ``scene`` key).

    Used for physically irrelevant changes of the reference (e.g. the part starting further
    upstream on the belt): how far the reference moves under them is its own numerical floor.
    """
    out = dict(scene)
    for key, value in (change or {}).items():
        if key not in out:
            raise FeederError(f"bench scene change: unknown scene key {key!r}")
        out[key] = merge_scene(out[key], value) if isinstance(value, dict) else value
    return out


def run_bench(scene, presets, labels_cfg, bench, progress=False):
    panel = [tuple(e) for e in bench["panel"]]
    drops = int(bench["drops"])
    seeds = [int(s) for s in bench["seeds"]]
    if len(seeds) != 2:
        raise FeederError("sim.bench.seeds must hold two seeds (reference pair)")
    ref_name = bench["reference"]
    if ref_name not in presets:
        raise FeederError(f"sim.bench.reference {ref_name!r} is not a preset")
    thickness = float(bench["thickness"])
    settings = {ref_name: dict(presets[ref_name])}
    scenes = {ref_name: scene}
    for s in bench["sweep"]:
        settings[s["name"]] = resolve_setting(presets, s)
        scenes[s["name"]] = merge_scene(scene, s.get("scene"))
    jobs = []
    for name, preset in settings.items():
        p = dict(preset, drops=drops)
        run_seeds = seeds if name == ref_name else [seeds[1]]
        for seed in run_seeds:
            for i, entry in enumerate(panel):
                jobs.append((name, p, seed, i, entry, scenes[name], thickness))
    # most expensive first (small internal steps, full path) so the pool stays busy
    jobs.sort(key=lambda j: -(j[1]["substeps"] / j[1]["time_step"]) * (3.0 if j[1]["full_path"] else 1.0))
    results = {}
    workers = max(1, int(bench["workers"]))
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(jobs), unit="run", file=sys.stderr)
    ctx = get_context("fork")
    with ctx.Pool(workers) as pool:
        for name, seed, idx, yaws, status, cpu in pool.imap_unordered(_run, jobs):
            results[(name, seed, idx)] = (yaws, status, cpu)
            if bar is not None:
                bar.update(1)
    if bar is not None:
        bar.close()
    out = summarize(results, settings, panel, seeds, ref_name, drops, bench, labels_cfg)
    changes = {s["name"]: json.dumps(s["scene"], sort_keys=True) for s in bench["sweep"] if s.get("scene")}
    out.insert(out.columns.get_loc("merge_tolerance") + 1, "scene_change", out["setting"].map(changes).fillna(""))
    return out


# The columns of the accuracy table, in order.
SUMMARY_COLUMNS = (
    "setting",
    "drops",
    "config",
    "time_step",
    "substeps",
    "internal_step_ms",
    "solver_iterations",
    "lanes",
    "full_path",
    "skip_slides",
    "merge_tolerance",
    "ms_per_drop",
    "speedup_vs_reference",
    "js",
    "js_floor",
    "js_floor_boot",
    "w1_deg",
    "w1_floor_deg",
    "r2_cdf",
    "r2_floor",
    "below_two_seed_floor",
    "js_excess",
    "js_excess_p",
    "w1_excess_deg",
    "w1_excess_p",
    "within_floor",
    "configs_within_boot_floor",
    "ok_rate",
    "ref_ok_rate",
)


def _config_row(results, name, seed, k, i, entry, seeds, ref_name, drops, bins, sigma, bench) -> dict:
    """One configuration's row at the first ``k`` drops: its distance from the reference (seed
    ``s0``) against the reference's own second seed (``s1``), and its bootstrap floor."""
    s0, s1 = seeds
    yaws, status, cpu = results[(name, seed, i)]
    ref_yaws = results[(ref_name, s0, i)][0]
    floor_yaws = results[(ref_name, s1, i)][0]
    js, w1, r2 = _metrics(yaws[:k], ref_yaws, bins, sigma)
    fjs, fw1, fr2 = _metrics(floor_yaws[:k], ref_yaws, bins, sigma)
    bjs = bootstrap_js_floor(
        ref_yaws,
        floor_yaws,
        k,
        bins,
        sigma,
        int(bench["boot_resamples"]),
        float(bench["boot_quantile"]),
        seed=i,
    )
    ok = float(np.mean(status[:k] == "ok"))
    ref_ok = float(np.mean(results[(ref_name, s0, i)][1] == "ok"))
    return dict(
        setting=name,
        drops=k,
        config=f"{entry[0]}|{entry[1]}|{entry[2]}",
        ms_per_drop=cpu * 1e3 / drops,
        js=js,
        w1_deg=w1,
        r2_cdf=r2,
        js_floor=fjs,
        js_floor_boot=bjs,
        w1_floor_deg=fw1,
        r2_floor=fr2,
        ok_rate=ok,
        ref_ok_rate=ref_ok,
    )


def _mean_row(per, results, name, seed, k, npanel, seeds, ref_name, ref_ms, bins, sigma, bench) -> dict:
    """A setting's mean row at ``k`` drops over its configuration rows ``per``, with its speed-up,
    the paired test against the reference's second seed and the count within the bootstrap floor."""
    import pandas as pd

    s0, s1 = seeds
    df = pd.DataFrame(per)
    ms = float(df["ms_per_drop"].mean())
    agg = dict(
        setting=name,
        drops=k,
        config="mean",
        ms_per_drop=ms,
        js=df["js"].mean(),
        w1_deg=df["w1_deg"].mean(),
        r2_cdf=df["r2_cdf"].mean(),
        js_floor=df["js_floor"].mean(),
        js_floor_boot=df["js_floor_boot"].mean(),
        w1_floor_deg=df["w1_floor_deg"].mean(),
        r2_floor=df["r2_floor"].mean(),
        ok_rate=df["ok_rate"].mean(),
        ref_ok_rate=df["ref_ok_rate"].mean(),
    )
    agg["speedup_vs_reference"] = ref_ms / ms if ms > 0 else np.nan
    agg["below_two_seed_floor"] = bool(agg["js"] <= agg["js_floor"] and agg["w1_deg"] <= agg["w1_floor_deg"])
    # paired test: farther from the reference than its own second seed, beyond sampling?
    triples = [
        (results[(name, seed, i)][0][:k], results[(ref_name, s1, i)][0][:k], results[(ref_name, s0, i)][0])
        for i in range(npanel)
    ]
    test = paired_excess(triples, bins, sigma, int(bench["boot_resamples"]), seed=k)
    alpha = 1.0 - float(bench["boot_quantile"])
    agg["js_excess"], agg["js_excess_p"] = test["js"]
    agg["w1_excess_deg"], agg["w1_excess_p"] = test["w1"]
    agg["within_floor"] = bool(test["js"][1] >= alpha and test["w1"][1] >= alpha)
    # per configuration against its bootstrap floor (95 % of sampling-only JS values)
    agg["configs_within_boot_floor"] = int((df["js"] <= df["js_floor_boot"]).sum())
    return agg


def _add_preset_columns(out, settings) -> None:
    """The preset values of each setting's rows, in place."""
    for name, preset in settings.items():
        m = out["setting"] == name
        out.loc[m, "time_step"] = preset["time_step"]
        out.loc[m, "substeps"] = preset["substeps"]
        out.loc[m, "internal_step_ms"] = 1e3 * preset["time_step"] / preset["substeps"]
        out.loc[m, "solver_iterations"] = preset["solver_iterations"]
        out.loc[m, "lanes"] = preset["lanes"]
        out.loc[m, "full_path"] = bool(preset["full_path"])
        out.loc[m, "skip_slides"] = bool(preset["skip_slides"])
        out.loc[m, "merge_tolerance"] = float(preset.get("merge_tolerance", 0.0))


def summarize(results, settings, panel, seeds, ref_name, drops, bench, labels_cfg):
    """The accuracy table (:data:`SUMMARY_COLUMNS`): per setting and drop level, a row per panel
    configuration (:func:`_config_row`) and their mean (:func:`_mean_row`)."""
    import pandas as pd

    bins, sigma = int(labels_cfg["bins"]), float(labels_cfg["sigma_bins"])
    levels = sorted({int(k) for k in bench["drop_levels"] if int(k) <= drops} | {drops})
    rows = []
    ref_ms = np.mean([results[(ref_name, s, i)][2] for s in seeds for i in range(len(panel))]) * 1e3 / drops
    for name in settings:
        seed = seeds[1]
        for k in levels:
            per = [
                _config_row(results, name, seed, k, i, entry, seeds, ref_name, drops, bins, sigma, bench)
                for i, entry in enumerate(panel)
            ]
            rows += per
            rows.append(_mean_row(per, results, name, seed, k, len(panel), seeds, ref_name, ref_ms, bins, sigma, bench))
    out = pd.DataFrame(rows)
    _add_preset_columns(out, settings)
    return out[list(SUMMARY_COLUMNS)]


def add_config_source(parser: argparse.ArgumentParser, sections: str) -> None:
    """``--settings`` JSON (the named config ``sections``) or ``--configfile`` overlays, exclusive."""
    source = parser.add_mutually_exclusive_group()
    source.add_argument(
        "--settings", default=None, help=f"JSON {{{sections}}} config sections; default config/config.yaml"
    )
    source.add_argument(
        "--configfile",
        nargs="+",
        default=[],
        help="config files laid over config/config.yaml (as snakemake --configfile)",
    )


def config_from_args(args: argparse.Namespace) -> dict:
    """The config chosen by :func:`add_config_source`'s options (files checked against the schema)."""
    if args.settings is not None:
        from feeder.config import parse_settings

        return parse_settings(args.settings)
    from feeder.config import load_study_config

    return load_study_config(*args.configfile, check=True)


def bench_cli(prog: str, doc: str, argv: list[str]) -> tuple[str, dict, dict, dict]:
    """The command line shared by the benchmarks (``--out-csv``, ``--settings``) → (out CSV path,
    scene, sim, labels): the sections from the ``--settings`` JSON string, else config/config.yaml."""
    parser = argparse.ArgumentParser(prog=prog, description=doc.splitlines()[0])
    parser.add_argument("--out-csv", required=True)
    add_config_source(parser, "scene, sim, labels")
    args = parser.parse_args(argv)
    cfg = config_from_args(args)
    try:
        return args.out_csv, cfg["scene"], cfg["sim"], cfg["labels"]
    except (KeyError, TypeError) as err:
        raise FeederError(f"settings lack section {err}") from None


def main(argv: list[str]) -> int:
    out_csv, scene, sim_cfg, labels_cfg = bench_cli("feeder bench-sim", __doc__, argv)
    try:
        presets, bench = sim_cfg["presets"], sim_cfg["bench"]
    except (KeyError, TypeError) as err:
        raise FeederError(f"settings lack section sim.{err.args[0]}") from None
    from feeder.io import write_csv

    df = run_bench(scene, presets, labels_cfg, bench, progress=sys.stderr.isatty())
    write_csv(out_csv, df)
    agg = df[(df["config"] == "mean") & (df["drops"] == df["drops"].max())]
    for _, r in agg.iterrows():
        print(
            f"{r['setting']:>16}: {r['ms_per_drop']:8.1f} ms/drop  x{r['speedup_vs_reference']:6.1f}  "
            f"JS {r['js']:.4f} (floor {r['js_floor']:.4f})  W1 {r['w1_deg']:.2f} (floor {r['w1_floor_deg']:.2f})  "
            f"R2 {r['r2_cdf']:.3f}  ok {r['ok_rate']:.3f}",
            file=sys.stderr,
        )
    return 0
