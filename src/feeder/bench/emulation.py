"""Emulated i.i.d. drops against real ones, for the partial-iteration studies (``feeder bench-emulation``).

The convergence studies (Figs. 4/5, Table 10) need i.i.d. drops in drop order: JS(P_N, P_1000)
between the PMF of a configuration's first N drops and of all of them. A ``grid`` or ``adaptive``
simulation has no such drops, so the study *emulates* them: ``labels.emulated_drops`` seeded
uniform initial yaws mapped through the sampled, interpolated drop map
(:func:`feeder.labels.pmf.level_drops`, :func:`feeder.sim.pushforward.emulate_drops`). This
bench checks that the emulated drops behave like real ones:

* ``feeder bench-emulation run --key KEY``, one job per configuration of
  ``sim.emulation_bench.configurations``: ``real_drops`` independent random drops simulated for
  real (the paper's design, :func:`feeder.sim.simulate.simulate` with ``yaw_sampling="random"``,
  seeded from the key), and the adaptive design at the study's budget (``sim.drops``) and
  settings (``sim.adaptive``). The raw arrays stay in the file (docs/data.md).
* ``feeder bench-emulation table``: per configuration and N of ``levels``, JS(P_N, P_all) of the
  real drops and of ``repeats`` seeded emulated realisations of ``real_drops`` drops each
  through the adaptive map (repeat 0 has the seed the study's dataset uses for that simulation,
  :func:`feeder.labels.pmf.emulation_seed`: the same drops when ``labels.emulated_drops`` equals
  ``real_drops``, in the part's own frame). JS is the convergence study's
  (:func:`feeder.labels.convergence.js_by_level`: ``labels.bins`` bins, wrapped Gaussian
  smoothing of ``labels.sigma_bins``, the ok drops among the first N, uniform if none). The
  summary, per N, compares the distributions over configurations with a Mann-Whitney U and a
  two-sample Kolmogorov-Smirnov test: real against the first emulated realisation (one value per
  configuration on each side: equal, independent samples; the verdict), real against all
  realisations pooled (more emulated values, but not independent: a configuration appears
  ``repeats`` times, so its p-values are optimistic), and a paired Wilcoxon signed-rank test of
  real minus first realisation per configuration (sharper against a systematic shift).

Two readings of the emulated JS. ``js`` compares the first N emulated drops with all of them,
as the real side does, and as the study does (:func:`feeder.labels.convergence.full_run_pmf`:
the 100 % level). ``js_label`` compares them with the configuration's exact push-forward label;
for real drops both are the same number. The summary tests both against the real drops (columns
``label_*`` for the second): a prefix approaches the exact label more slowly than its own full
run, so that reading is not the paper's quantity (the study used it until 2026-11-22; this
bench found it).

The JS test only says the emulated drops have the sampling behaviour of real ones; whether the
map puts the mass in the right place is the sup|ΔCDF| between the real ``real_drops``-drop label
and the adaptive push-forward label, per configuration in the rows (``sup_cdf_label``, next to
the DKW half-width of the real label, ``dkw_epsilon``; its median in the summary).

The configurations default to the 32 of ``results/convergence1000`` (1,000 real drops each). That
run used the rigid belt; this bench is about the initial-yaw design, so it simulates the study's
current scene (``scene``, compliant belt) and does not reproduce that run bit for bit. Configurations
whose real ok fraction or adaptive ok mass is below ``sim.min_ok_mass`` (the study would drop them)
are kept in the rows (``usable`` false) and left out of the summary.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from feeder.errors import FeederError

ALPHA = 0.05  # the tests' significance level: the verdict is "agree" when no test rejects at it
SOURCES = ("real", "emulated")
RUN_KEYS = (
    "real_initial",
    "real_final",
    "real_status",
    "real_cpu_s",
    "adaptive_initial",
    "adaptive_final",
    "adaptive_status",
    "adaptive_cpu_s",
    "meta",
)


# ----------------------------------------------------------------------------------------------
# Configurations
# ----------------------------------------------------------------------------------------------
def entries(settings: dict) -> list[dict]:
    """The bench's configurations (``sim.emulation_bench.configurations``: part ids of
    ``parts.dir`` with two fence locations), each with a file-safe key (``part__config``)."""
    from feeder.bench.reference import keyed_entries

    out = [
        {"kind": "part", "part": e[0], "loc1": e[1], "loc2": e[2]} for e in bench_settings(settings)["configurations"]
    ]
    return keyed_entries(out, "sim.emulation_bench.configurations")


def bench_settings(settings: dict) -> dict:
    eb = settings.get("sim", {}).get("emulation_bench")
    if eb is None:
        raise FeederError("settings lack section sim.emulation_bench")
    return eb


def run_settings(config: dict, key: str) -> str:
    """The ``--settings`` JSON of one ``run`` job (the workflow's param): the scene, ``parts.dir``,
    the bench's preset, real drops and seed, the study's budget and adaptive settings, and only
    this job's configuration (none for an unknown key: the command then names it), so that
    adding a configuration or editing the table's settings reruns no simulation."""
    from feeder.workflow import select_settings

    eb = bench_settings(config)
    keys = ["scene", "parts.dir", "sim.drops", "sim.adaptive", f"sim.presets.{eb['preset']}"]
    picked = json.loads(
        select_settings(config, *keys, *(f"sim.emulation_bench.{k}" for k in ("preset", "real_drops", "seed")))
    )
    mine = [[e["part"], e["loc1"], e["loc2"]] for e in entries(config) if e["key"] == key]
    picked["sim"]["emulation_bench"]["configurations"] = mine
    return json.dumps(picked, sort_keys=True, separators=(",", ":"))


def entry_by_key(settings: dict, key: str) -> dict:
    entry = {e["key"]: e for e in entries(settings)}.get(key)
    if entry is None:
        raise FeederError(f"no configuration {key!r} in sim.emulation_bench (feeder bench-emulation list)")
    return entry


# ----------------------------------------------------------------------------------------------
# One configuration (simulation)
# ----------------------------------------------------------------------------------------------
def run_entry(entry: dict, settings: dict) -> dict:
    """``real_drops`` independent random drops and the adaptive design of one configuration,
    simulated for real: the arrays of its run file (:func:`run_arrays`)."""
    from feeder.bench.reference import seed_of
    from feeder.lane.fences import parse_location
    from feeder.parts.geometry import load_part
    from feeder.sim.drops import get_preset
    from feeder.sim.simulate import simulate

    eb, sim = bench_settings(settings), settings["sim"]
    preset = get_preset(sim["presets"], eb["preset"])
    path = Path(settings["parts"]["dir"]) / f"{entry['part']}.stl"
    if not path.is_file():
        raise FeederError(f"sim.emulation_bench.configurations: part file {path} not found")
    geom = load_part(path)
    loc1, loc2 = parse_location(entry["loc1"]), parse_location(entry["loc2"])
    common = (geom, loc1, loc2)
    real_seed = seed_of(entry["key"], "real", int(eb["seed"]))
    real = simulate(*common, int(eb["real_drops"]), real_seed, settings["scene"], preset, eb["preset"])
    adaptive = simulate(
        *common,
        int(sim["drops"]),
        int(eb["seed"]),
        settings["scene"],
        preset,
        eb["preset"],
        yaw_sampling="adaptive",
        adaptive=dict(sim["adaptive"]),
    )
    return run_arrays(entry, eb["preset"], real, adaptive)


def run_arrays(entry: dict, preset_name: str, real: dict, adaptive: dict) -> dict:
    """A run file's arrays from two :func:`feeder.sim.simulate.simulate` results (pure): ``real_*``
    and ``adaptive_*`` initial/final yaws, statuses and CPU seconds, and ``meta`` (JSON: entry,
    preset, and each simulation's own meta as ``real`` and ``adaptive``)."""
    out = {}
    for tag, res in (("real", real), ("adaptive", adaptive)):
        out |= {
            f"{tag}_initial": np.asarray(res["initial_yaw_deg"], dtype=np.float64),
            f"{tag}_final": np.asarray(res["final_yaw_deg"], dtype=np.float64),
            f"{tag}_status": np.asarray(res["status"]).astype(str),
            f"{tag}_cpu_s": np.float64(res["cpu_s"]),
        }
    meta = {
        "entry": entry,
        "preset": preset_name,
        "real": json.loads(str(real["meta"])),
        "adaptive": json.loads(str(adaptive["meta"])),
    }
    return out | {"meta": np.array(json.dumps(meta, sort_keys=True))}


# ----------------------------------------------------------------------------------------------
# The table (pure: reads the run files)
# ----------------------------------------------------------------------------------------------
def load_run(path: Path) -> dict:
    """A run file's arrays, ``meta`` parsed; a missing or short file is a one-line error."""
    from feeder.io import read_npz

    run = read_npz(path, RUN_KEYS, what="emulation run file")
    try:
        meta = json.loads(str(run["meta"]))
    except json.JSONDecodeError:
        meta = None
    if not (isinstance(meta, dict) and "key" in (meta.get("entry") or {}) and "design" in (meta.get("adaptive") or {})):
        raise FeederError(f"emulation run file {path}: meta is not the JSON feeder bench-emulation run writes")
    run["meta"] = meta
    run["path"] = str(path)
    return run


def adaptive_record(run: dict):
    """The adaptive simulation of a run file as a :class:`feeder.sim.record.SimRecord`."""
    from feeder.sim.record import SimRecord

    status = run["adaptive_status"]
    return SimRecord(
        yaws=np.where(status == "ok", run["adaptive_final"], np.nan),
        ok=status == "ok",
        meta=run["meta"]["adaptive"],
        initial=run["adaptive_initial"],
        status=status,
    )


def prefix_pmfs(final, ok, levels, bins: int, sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """PMFs of the first N drops for every N of ``levels`` and of all drops, as the convergence
    study builds them (:func:`feeder.labels.metrics.partial_pmfs`: the ok drops among the first
    N, smoothed; uniform if none). Returns (level PMFs (L, bins), full PMF (bins,), ok drops per level)."""
    from feeder.labels import metrics as L

    final = np.asarray(final, dtype=np.float64)
    ok = np.asarray(ok, dtype=bool)
    pmfs, n_ok = [], []
    for n in list(levels) + [final.size]:
        p, k = L.partial_pmfs(final[: int(n)], [100], bins, sigma, ok=ok[: int(n)])
        pmfs.append(p[0])
        n_ok.append(int(k[0]))
    return np.stack(pmfs[:-1]), pmfs[-1], np.array(n_ok[:-1])


def prefix_js(level_pmfs: np.ndarray, full_pmf: np.ndarray) -> np.ndarray:
    """JS(P_N, P_full) in bits for every level: the convergence study's definition."""
    from feeder.labels.convergence import js_by_level

    return js_by_level({"pmf_levels": level_pmfs[None], "pmf": full_pmf[None]})[0]


def emulation_seeds(run: dict, repeats: int, seed: int) -> list[int]:
    """Seeds of the emulated realisations: repeat 0 is the study's own (seeded from the adaptive
    simulation's part, configuration and base seed), the others are seeded from the key."""
    from feeder.bench.reference import seed_of
    from feeder.labels.pmf import emulation_seed

    key = run["meta"]["entry"]["key"]
    return [emulation_seed(adaptive_record(run))] + [seed_of(key, "emulated", seed, r) for r in range(1, repeats)]


def entry_rows(run: dict, settings: dict) -> list[dict]:
    """Rows of one run file: per N of ``levels``, the real drops' JS and each emulated
    realisation's, with the configuration's context columns (see the module doc)."""
    from feeder.labels import metrics as L
    from feeder.labels.pmf import record_design, sim_label
    from feeder.sim.pushforward import emulate_drops

    eb, labels = bench_settings(settings), settings["labels"]
    bins, sigma = int(labels["bins"]), float(labels["sigma_bins"])
    min_ok_mass = float(settings["sim"]["min_ok_mass"])
    entry = run["meta"]["entry"]
    n_real = int(run["real_final"].size)
    if n_real != int(eb["real_drops"]):
        raise FeederError(
            f"{run['path']} holds {n_real} real drops, sim.emulation_bench.real_drops is {eb['real_drops']} (rerun it)"
        )
    levels = [int(n) for n in eb["levels"]]
    if max(levels) > n_real:
        raise FeederError(f"sim.emulation_bench.levels: {max(levels)} drops exceed the {n_real} real drops")

    real_ok = run["real_status"] == "ok"
    rec = adaptive_record(run)
    ada_label = sim_label(rec, bins, sigma) if rec.ok.any() else None
    context = {
        "config": entry["key"],
        "part": entry["part"],
        "loc1": entry["loc1"],
        "loc2": entry["loc2"],
        "real_drops": n_real,
        "real_ok_fraction": float(real_ok.mean()),
        "real_cpu_s": float(run["real_cpu_s"]),
        "adaptive_simulations": int(run["adaptive_final"].size),
        "adaptive_ok_mass": math.nan if ada_label is None else ada_label.ok_mass,
        "adaptive_unresolved_share": math.nan if ada_label is None else ada_label.cdf_bound,
        "adaptive_cpu_s": float(run["adaptive_cpu_s"]),
    }
    usable = ada_label is not None and real_ok.any()
    context["usable"] = bool(
        usable and context["real_ok_fraction"] >= min_ok_mass and context["adaptive_ok_mass"] >= min_ok_mass
    )
    if not usable:  # no label on one side: nothing to compare
        context |= {"sup_cdf_label": math.nan, "dkw_epsilon": math.nan}
        base = dict.fromkeys(("js", "js_label", "n_ok"), math.nan)
        rows = [{**context, "n_drops": n, "source": "real", "repeat": 0, **base} for n in levels]
        return rows + [
            {**context, "n_drops": n, "source": "emulated", "repeat": r, **base}
            for r in range(int(eb["repeats"]))
            for n in levels
        ]

    real_levels, real_pmf, real_n_ok = prefix_pmfs(run["real_final"], real_ok, levels, bins, sigma)
    context["sup_cdf_label"] = float(L.ks(L.cdf(real_pmf), L.cdf(ada_label.pmf)))
    context["dkw_epsilon"] = float(L.dkw_epsilon(int(real_ok.sum()), ALPHA))
    real_js = prefix_js(real_levels, real_pmf)
    rows = [
        {**context, "n_drops": n, "source": "real", "repeat": 0, "js": float(j), "js_label": float(j), "n_ok": int(k)}
        for n, j, k in zip(levels, real_js, real_n_ok, strict=True)
    ]
    design = record_design(rec)
    for r, seed in enumerate(emulation_seeds(run, int(eb["repeats"]), int(eb["seed"]))):
        final, status = emulate_drops(design, n_real, seed)
        emu_levels, emu_pmf, emu_n_ok = prefix_pmfs(final, status == "ok", levels, bins, sigma)
        js, js_label = prefix_js(emu_levels, emu_pmf), prefix_js(emu_levels, ada_label.pmf)
        rows += [
            {
                **context,
                "n_drops": n,
                "source": "emulated",
                "repeat": r,
                "js": float(a),
                "js_label": float(b),
                "n_ok": int(k),
            }
            for n, a, b, k in zip(levels, js, js_label, emu_n_ok, strict=True)
        ]
    return rows


def _tests(real: np.ndarray, emulated: np.ndarray) -> tuple[float, float]:
    """Mann-Whitney U and two-sample KS p-values (two-sided); NaN with fewer than 2 on a side."""
    from scipy import stats

    if real.size < 2 or emulated.size < 2:
        return math.nan, math.nan
    return (
        float(stats.mannwhitneyu(real, emulated, alternative="two-sided").pvalue),
        float(stats.ks_2samp(real, emulated).pvalue),
    )


def _paired(real: np.ndarray, emulated: np.ndarray) -> float:
    """Wilcoxon signed-rank p-value of real − emulated per configuration (NaN if undefined)."""
    from scipy import stats

    d = real - emulated
    if d.size < 2 or not np.any(d != 0):
        return math.nan
    return float(stats.wilcoxon(real, emulated).pvalue)


def verdict(*p_values: float, alpha: float = ALPHA) -> str:
    """``agree`` when no test rejects at ``alpha``, ``differ`` when one does, ``n/a`` without tests."""
    if any(math.isnan(p) for p in p_values):
        return "n/a"
    return "agree" if min(p_values) >= alpha else "differ"


def summary(frame, alpha: float = ALPHA):
    """Per N: median / mean JS of the real drops and of the emulated ones, the tests' p-values and
    verdicts (module doc), over the usable configurations; the median sup|ΔCDF| of the labels."""
    import pandas as pd

    use = frame[frame["usable"].astype(bool)]
    excluded = frame["config"].nunique() - use["config"].nunique()
    rows = []
    for n, g in use.groupby("n_drops", sort=True):
        real = g[g["source"] == "real"].sort_values("config")
        emu = g[g["source"] == "emulated"]
        first = emu[emu["repeat"] == 0].sort_values("config")
        if list(real["config"]) != list(first["config"]):
            raise FeederError(f"N = {n}: the real and the first emulated rows cover different configurations")
        r, e1, pooled = real["js"].to_numpy(), first["js"].to_numpy(), emu["js"].to_numpy()
        to_label = first["js_label"].to_numpy()
        mw, ks = _tests(r, e1)
        mw_pooled, ks_pooled = _tests(r, pooled)
        label_mw, label_ks = _tests(r, to_label)
        rows.append(
            {
                "n_drops": int(n),
                "configurations": len(r),
                "excluded_configurations": int(excluded),
                "repeats": int(emu["repeat"].nunique()),
                "real_median_js": float(np.median(r)),
                "real_mean_js": float(r.mean()),
                "emulated_median_js": float(np.median(e1)),
                "emulated_mean_js": float(e1.mean()),
                "emulated_pooled_median_js": float(np.median(pooled)),
                "emulated_pooled_mean_js": float(pooled.mean()),
                "mannwhitney_p": mw,
                "ks_p": ks,
                "wilcoxon_paired_p": _paired(r, e1),
                "mannwhitney_p_pooled": mw_pooled,
                "ks_p_pooled": ks_pooled,
                "alpha": alpha,
                "verdict": verdict(mw, ks, alpha=alpha),
                "verdict_pooled": verdict(mw_pooled, ks_pooled, alpha=alpha),
                "label_emulated_median_js": float(np.median(to_label)),
                "label_emulated_mean_js": float(to_label.mean()),
                "label_mannwhitney_p": label_mw,
                "label_ks_p": label_ks,
                "label_verdict": verdict(label_mw, label_ks, alpha=alpha),
                "median_sup_cdf_label": float(real["sup_cdf_label"].median()),
                "median_dkw_epsilon": float(real["dkw_epsilon"].median()),
            }
        )
    return pd.DataFrame(rows)


# ----------------------------------------------------------------------------------------------
# CLI
# ----------------------------------------------------------------------------------------------
def main(argv: list[str]) -> int:
    from feeder.config import add_settings_options, study_settings
    from feeder.io import write_csv, write_npz

    parser = argparse.ArgumentParser(prog="feeder bench-emulation", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    add_settings_options(sub.add_parser("list", help="the configuration keys"))
    run = add_settings_options(
        sub.add_parser("run", help="real random drops and the adaptive design of one configuration")
    )
    run.add_argument("--key", required=True, help="configuration key (feeder bench-emulation list)")
    run.add_argument("--out", required=True, type=Path)
    table = add_settings_options(
        sub.add_parser("table", help="JS(P_N, P_all) of real and emulated drops, and the tests")
    )
    table.add_argument("--runs", nargs="+", required=True, type=Path, help="run files (feeder bench-emulation run)")
    table.add_argument("--out-csv", required=True, type=Path, help="one row per configuration, N, source and repeat")
    table.add_argument("--out-summary", required=True, type=Path, help="per N: medians, p-values and verdicts")
    args = parser.parse_args(argv)
    settings = study_settings(args)
    bench_settings(settings)
    if args.cmd == "list":
        print("\n".join(e["key"] for e in entries(settings)))
        return 0
    if args.cmd == "run":
        write_npz(args.out, **run_entry(entry_by_key(settings, args.key), settings))
        return 0
    import pandas as pd

    runs = [load_run(p) for p in args.runs]
    keys = [r["meta"]["entry"]["key"] for r in runs]
    if len(set(keys)) != len(keys):
        raise FeederError("--runs names a configuration twice")
    frame = pd.DataFrame([row for r in runs for row in entry_rows(r, settings)])
    means = summary(frame)
    write_csv(args.out_csv, frame)
    write_csv(args.out_summary, means)
    for _, r in means.iterrows():
        print(
            f"N {int(r['n_drops']):5d}: JS median real {r['real_median_js']:.4f} emulated {r['emulated_median_js']:.4f}"
            f"  MWU p {r['mannwhitney_p']:.3f}  KS p {r['ks_p']:.3f}  {r['verdict']}"
            f"  (to the label: {r['label_emulated_median_js']:.4f}, {r['label_verdict']})",
            file=sys.stderr,
        )
    return 0
