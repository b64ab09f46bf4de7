"""What an answer costs for a known part at a new angle (``feeder bench-frontier-known``).

Issue #39 item 4, on the study's own held-out configurations: the dataset's Test split (the parts
of its Main split at fence angles no model trained on), scored against the study's labels. The
dense-map frontier (``feeder bench-frontier``) has the design bench's 20 configurations, mostly of
parts no model has seen; this one has the configurations the structured predictor is shipped for.

Every answer is scored by circular W1 (and sup|ΔCDF|) against the configuration's label in the
dataset (the study's adaptive design at ``sim.drops``), in the label frame:

* ``mean_pmf``: the mean training label (a lookup);
* ``analytic``: the analytic push PMF;
* ``neighbour_gated``: the part's nearest training label of the same fence types within the gate
  chosen on the training rows (``feeder.learn.neighbour``), else the analytic PMF;
* the shipped models named in ``sim.frontier_known.models`` (trained on the dataset's training
  split, so Test is held out from them);
* ``structured``: the structured predictor fitted here as ``feeder fit-structured`` fits it, on the
  training split only (its validation parts, search and seeds), answering each Test configuration
  from the part's training labels through :class:`feeder.learn.structured_shipped.ShippedStructured`,
  the code ``feeder predict`` runs (the fit is kept in the work folder);
* ``simulate<B>``: ``feeder simulate`` at each budget ``B`` of ``sim.frontier_known.budgets``, the
  study's adaptive design (below ``sim.adaptive.n0`` an evenly spaced grid of ``B`` drops), with a
  base seed of its own (``sim.frontier_known.seed + B``, never the study's), on
  ``sim.frontier_known.configurations`` Test configurations drawn by a seeded hash of their ids.
  Each simulation file is kept (``<work>/sim/<part>/<config>__b<B>.npz``) and reused on a rerun.

The reference is itself a label at the study's budget, so ``simulate<sim.drops>`` measures how far
two labels of the same configuration lie apart, not the error of either against the exact answer:
differences of that size are not resolved. CPU seconds per answer: each predictor timed over ``repeats`` calls
on the simulated configurations (``time.process_time``, the median per configuration; a fresh
process adds its start-up); a simulation's own measured CPU time.

Writes one row per configuration and answer (``--out-raw``: a new statistic needs no rerun) and a
summary (``--out-csv``) for two sets of configurations: ``all``, the simulated ones, where every
answer has a row (the frontier, ``feeder figure frontier_known``), and ``test``, every kept Test
configuration (predictors only), each with a 95 % bootstrap interval over configurations and, for
the structured predictor, its paired difference to every other predictor.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from feeder.errors import FeederError

MEAN_PMF, ANALYTIC, NEIGHBOUR, STRUCTURED = "mean_pmf", "analytic", "neighbour_gated", "structured"
SETS = ("all", "test")  # the simulated configurations (every answer), every kept Test configuration
FIT_FILE = "structured_train.npz"


def check_frontier_known(settings: dict) -> dict:
    """``sim.frontier_known`` checked: configurations, budgets, models, seed, repeats, resamples."""
    try:
        fk = settings["sim"]["frontier_known"]
        out = {
            "configurations": int(fk["configurations"]),
            "budgets": [int(b) for b in fk["budgets"]],
            "models": [str(m) for m in fk["models"]],
            "seed": int(fk["seed"]),
            "repeats": int(fk["repeats"]),
            "resamples": int(fk["resamples"]),
        }
        base_seed = int(settings["sim"]["base_seed"])
    except (KeyError, TypeError, ValueError) as err:
        raise FeederError(f"--settings lacks or mistypes sim.frontier_known: {err}") from None
    if out["configurations"] < 1:
        raise FeederError(f"sim.frontier_known.configurations must be at least 1 (got {out['configurations']})")
    if not out["budgets"] or min(out["budgets"]) < 2:
        raise FeederError(f"sim.frontier_known.budgets: budgets of at least 2 drops (got {out['budgets']})")
    if out["repeats"] < 1 or out["resamples"] < 1:
        raise FeederError("sim.frontier_known: repeats and resamples must be at least 1")
    clash = [b for b in out["budgets"] if replicate_seed(out["seed"], b) == base_seed]
    if clash:
        raise FeederError(
            f"sim.frontier_known.seed {out['seed']}: budget {clash[0]} would reuse the study's base seed "
            f"{base_seed} (its simulations are the reference)"
        )
    return out


def replicate_seed(seed: int, budget: int) -> int:
    """The base seed of the replicate simulations at ``budget`` (pure)."""
    return int(seed) + int(budget)


def source_digest(*modules: str) -> str:
    """SHA-256 of the source of ``modules`` and every ``feeder`` module they import (the files a
    rule's code inputs list): a kept fit or simulation file is reused only under the same code."""
    from feeder.workflow import code_modules, module_file

    root = Path(__file__).resolve().parents[2]
    h = hashlib.sha256()
    for module in code_modules(*modules, root=root):
        h.update(module.encode())
        h.update(Path(module_file(module, root)).read_bytes())
    return h.hexdigest()


def _digest(a) -> str:
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()


def fit_key(arrays: dict, train, cfg, data: dict) -> str:
    """What a kept fit must match to be reused: the settings, the training rows' ids, labels and
    inputs, the label settings and frame, and the fitting code."""
    from omegaconf import OmegaConf

    train = np.asarray(train, dtype=bool)
    made = json.loads(str(data["settings"]))
    inputs = [_digest(np.asarray(arrays[k])[train]) for k in ("x", "analytic", "ok", "frame_deg", "pmf", "kept")]
    return hashlib.sha256(
        json.dumps(
            [
                OmegaConf.to_container(cfg, resolve=True),
                [str(a) for a in np.asarray(arrays["part"])[train]],
                [str(a) for a in np.asarray(arrays["config_id"])[train]],
                inputs,
                made.get("labels"),
                str(data["label_frame"]),
                source_digest("feeder.learn.structured_shipped", "feeder.learn.structured_protocol"),
            ],
            sort_keys=True,
        ).encode()
    ).hexdigest()


def replicate_request(stl: Path, budget: int, seed: int, settings: dict) -> str:
    """What a kept simulation file must match to be reused: budget, seed, design, scene, preset,
    units, the part file's bytes and the simulator's code."""
    from feeder.bench.frontier import budget_design

    sim = settings["sim"]
    request = {
        "budget": int(budget),
        "seed": int(seed),
        "design": budget_design(sim["adaptive"], budget),
        "scene": settings["scene"],
        "preset": sim["presets"][sim["preset"]],
        "units": settings["parts"]["units"],
        "part_sha256": hashlib.sha256(Path(stl).read_bytes()).hexdigest(),
        "code": source_digest("feeder.sim.simulate"),
    }
    return json.dumps(request, sort_keys=True)


def pick_rows(parts, config_ids, rows, n: int, seed: int) -> np.ndarray:
    """The ``n`` of ``rows`` first by sha256(seed:part:config), in index order (pure): the same
    configurations for the same ids whatever else the dataset holds."""
    rows = np.asarray(rows, dtype=np.int64)
    rank = [hashlib.sha256(f"{seed}:{parts[i]}:{config_ids[i]}".encode()).hexdigest() for i in rows]
    return np.sort(rows[np.argsort(rank, kind="stable")[: int(n)]])


def scores(pmf, ref_pmf) -> dict[str, float]:
    """Circular W1 (degrees) and sup|ΔCDF| of an answer against the reference label."""
    from feeder.labels import metrics as L

    a, b = L.cdf(np.asarray(pmf, np.float64)), L.cdf(np.asarray(ref_pmf, np.float64))
    return {"circular_w1_deg": float(L.circular_w1(a, b)), "sup_cdf": float(L.ks(a, b))}


def summary(raw: pd.DataFrame, resamples: int, seed: int) -> pd.DataFrame:
    """Per set of configurations and answer: n, mean CPU seconds, mean circular W1 and sup|ΔCDF|
    with 95 % bootstrap intervals (``n``: configurations with a finite score; ``n_timed``: those
    timed, over which ``cpu_s_mean`` is taken); for every answer but the structured predictor, the
    structured predictor's paired difference in circular W1 on the same configurations (``diff_*``)."""
    from feeder.bench.frontier import bootstrap_mean
    from feeder.learn.evaluate import paired_bootstrap

    rows = []
    for subset in SETS:
        frame = raw if subset == "test" else raw[raw["simulated"].astype(bool)]
        if subset == "test":
            frame = frame[frame["kind"] == "predictor"]
        if frame.empty:
            continue
        ours = frame[frame["answer"] == STRUCTURED].set_index("config")["circular_w1_deg"].dropna()
        for (answer, kind, budget), g in frame.groupby(["answer", "kind", "budget"], sort=False):
            g = g[np.isfinite(g["circular_w1_deg"].astype(float))]  # an answer without a PMF is no score
            if g.empty:
                continue
            w1 = bootstrap_mean(g["circular_w1_deg"], resamples, seed)
            sup = bootstrap_mean(g["sup_cdf"], resamples, seed)
            row = {
                "configurations": subset,
                "answer": answer,
                "kind": kind,
                "budget": int(budget),
                "n": len(g),
                "n_timed": int(np.isfinite(g["cpu_s"].astype(float)).sum()),
                "cpu_s_mean": float(g["cpu_s"].mean()),
                "circular_w1_deg": w1[0],
                "circular_w1_low": w1[1],
                "circular_w1_high": w1[2],
                "sup_cdf": sup[0],
                "sup_cdf_low": sup[1],
                "sup_cdf_high": sup[2],
                "diff": np.nan,
                "diff_low": np.nan,
                "diff_high": np.nan,
            }
            both = g.set_index("config")["circular_w1_deg"].align(ours, join="inner")
            if answer != STRUCTURED and len(both[0]):
                d = paired_bootstrap((both[1] - both[0]).to_numpy(), resamples, 0.95, seed)
                row.update(diff=d[0], diff_low=d[1], diff_high=d[2])
            rows.append(row)
    return pd.DataFrame(rows).sort_values(["configurations", "cpu_s_mean"], ignore_index=True)


# ----------------------------------------------------------------------------------------------
# The answers
# ----------------------------------------------------------------------------------------------
def _timed(fn, repeats: int) -> tuple[object, float]:
    """(the last result of ``fn()``, the median CPU seconds of ``repeats`` calls)."""
    times, out = [], None
    for _ in range(int(repeats)):
        t0 = time.process_time()
        out = fn()
        times.append(time.process_time() - t0)
    return out, float(np.median(times))


def structured_fit(arrays: dict, train, cfg, data: dict, path: Path, say):
    """The structured predictor fitted on ``train`` rows (``feeder fit-structured``'s fit), read
    from ``path`` when a fit of the same rows and settings is there, else fitted and written."""
    from feeder import io
    from feeder.learn.structured_shipped import ShippedStructured, fit_shipped

    key = fit_key(arrays, train, cfg, data)
    if path.is_file():
        with np.load(path, allow_pickle=False) as z:
            if "fit_key" in z.files and str(z["fit_key"]) == key:
                say(f"structured predictor: the fit in {path}")
                return ShippedStructured({k: z[k] for k in z.files if k != "fit_key"})
    say(f"structured predictor: fitting on {int(np.sum(train & arrays['kept']))} training configurations")
    out = fit_shipped(arrays, cfg, data, train)
    io.write_npz(path, fit_key=np.array(key), **out)
    return ShippedStructured(out)


def structured_answers(shipped, arrays, rows, pool, parts_dir: Path, scene: dict, timed, repeats: int):
    """``{row: (PMF in the label frame, CPU seconds per answer or NaN)}`` of the structured
    predictor for ``rows`` from each part's ``pool`` rows; rows in ``timed`` answered one at a time
    ``repeats`` times (geometry, candidates and network: what a ``feeder predict`` query costs)."""
    from feeder.mechanics.hull import push_geometry
    from feeder.parts.geometry import load_profile

    out = {}
    parts = np.asarray(arrays["part"]).astype(str)
    cids = np.asarray(arrays["config_id"]).astype(str)
    for part in sorted(set(parts[rows])):
        mine = [int(i) for i in rows if parts[i] == part]
        p_rows = [int(j) for j in np.flatnonzero(pool & (parts == part))]
        stl = parts_dir / f"{part}.stl"

        def answer(queries, stl=stl, part=part, p_rows=p_rows):
            outline, holes, _ = load_profile(stl, shipped.units)
            return shipped.answer(
                push_geometry(outline, holes),
                part,
                [cids[i] for i in queries],
                [cids[j] for j in p_rows],
                arrays["pmf"][p_rows],
                arrays["ok"][p_rows],
                scene,
            )

        pmf = answer(mine)
        for n, i in enumerate(mine):
            seconds = np.nan
            if i in timed:
                _, seconds = _timed(lambda i=i: answer([i]), repeats)
            out[i] = (pmf[n], seconds)
    return out


def model_answers(model, data: dict, rows, parts_dir: Path, timed, repeats: int, study: dict) -> dict:
    """``{row: (PMF in the label frame, CPU seconds or NaN)}`` of a shipped model on dataset rows
    (its inputs as the dataset has them); rows in ``timed`` timed as a query from the part's STL
    (:func:`feeder.learn.predict.part_vector`, :func:`~feeder.learn.predict.push_inputs`, the model)."""
    from feeder.labels.dataset import feeder_vector
    from feeder.lane.fences import parse_config_id
    from feeder.learn.predict import part_vector, push_inputs

    push = np.asarray(data["push_raw"])[rows] if model.needs_push else None
    analytic = np.asarray(data["pmf_analytic"])[rows] if model.needs_analytic else None
    pmf, _ = model.predict(np.asarray(data["part_raw"])[rows], np.asarray(data["feeder_raw"])[rows], push, analytic)
    out = {}
    for n, i in enumerate(rows):
        seconds = np.nan
        if i in timed:
            stl = parts_dir / f"{data['part'][i]}.stl"
            pair = parse_config_id(str(data["config_id"][i]))

            def query(stl=stl, pair=pair):
                part_raw, frame = part_vector(stl, None, scene=study["scene"])
                p, a = push_inputs(model, stl, [pair], frame, study)
                return model.predict(part_raw[None, :], feeder_vector(*pair)[None, :], p, a)

            _, seconds = _timed(query, repeats)
        out[int(i)] = (pmf[n], seconds)
    return out


def analytic_seconds(stl: Path, config_id: str, study: dict, repeats: int) -> float:
    """CPU seconds of the analytic push PMF of one query (outline, then the push model)."""
    from feeder.labels.dataset import label_smooth_deg
    from feeder.lane.fences import parse_config_id
    from feeder.mechanics.features import push_block
    from feeder.mechanics.hull import push_geometry
    from feeder.parts.geometry import load_profile

    loc1, loc2 = parse_config_id(config_id)
    labels = study["labels"]

    def query():
        outline, holes, _ = load_profile(stl, str(study.get("units", "auto")))
        smooth = label_smooth_deg(int(labels["bins"]), float(labels["sigma_bins"]))
        return push_block(
            push_geometry(outline, holes), loc1, loc2, study["scene"], bins=int(labels["bins"]), pmf_smooth_deg=smooth
        )

    return _timed(query, repeats)[1]


def replicate_label(
    stl: Path, config_id: str, budget: int, seed: int, settings: dict, frame_deg: float, path: Path
) -> tuple[np.ndarray | None, float, int]:
    """(label PMF in the label frame or None when no drop ended ok, CPU seconds, simulations) of
    ``feeder simulate`` at ``budget`` with base seed ``seed``; the file at ``path`` is written
    atomically and reused when it holds the same request."""
    from feeder.bench.frontier import budget_design
    from feeder.io import write_npz
    from feeder.labels.dataset import label_yaws
    from feeder.labels.pmf import sim_label
    from feeder.lane.fences import parse_config_id
    from feeder.parts.geometry import load_part_units
    from feeder.sim.drops import get_preset
    from feeder.sim.record import DESIGN_KEYS, SIM_KEYS, load_sim, record_of
    from feeder.sim.simulate import simulate

    sim, labels = settings["sim"], settings["labels"]
    design = budget_design(sim["adaptive"], budget)
    request = replicate_request(stl, budget, seed, settings)
    rec = None
    if path.is_file():
        with np.load(path, allow_pickle=False) as z:
            if "request" in z.files and str(z["request"]) == request:
                cpu = float(z["cpu_s"])
                rec = load_sim(path, 0)
    if rec is None:
        geom, _ = load_part_units(stl, str(settings["parts"]["units"]))
        loc1, loc2 = parse_config_id(config_id)
        preset = get_preset(sim["presets"], sim["preset"])
        res = simulate(
            geom,
            loc1,
            loc2,
            int(budget),
            int(seed),
            settings["scene"],
            preset,
            sim["preset"],
            yaw_sampling="adaptive",
            adaptive=design,
        )
        write_npz(path, request=np.array(request), **{k: res[k] for k in SIM_KEYS + DESIGN_KEYS if k in res})
        rec, cpu = record_of(res), float(res["cpu_s"])
    n = int(rec.yaws.size)
    if not rec.ok.any():
        return None, cpu, n
    if str(labels.get("frame", "part")) == "principal":
        rec.yaws = label_yaws(rec.yaws, "principal", float(frame_deg))
    return sim_label(rec, int(labels["bins"]), float(labels["sigma_bins"])).pmf, cpu, n


# ----------------------------------------------------------------------------------------------
# CLI
# ----------------------------------------------------------------------------------------------
def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="feeder bench-frontier-known", description=__doc__.splitlines()[0])
    parser.add_argument("--settings", required=True, help="JSON {scene, sim, labels, parts, models} config sections")
    parser.add_argument("--dataset", type=Path, required=True, help="results/datasets/dataset.npz")
    parser.add_argument("--sim-dir", type=Path, required=True, help="results/sim (the ok shares)")
    parser.add_argument("--parts-dir", type=Path, required=True, help="the parts' STLs (parts)")
    parser.add_argument("--features-dir", type=Path, required=True, help="results/features")
    parser.add_argument("--cache", type=Path, default=None, help="the structured predictor's candidates cache (.npz)")
    parser.add_argument("--work-dir", type=Path, required=True, help="kept: the fit and the simulation files")
    parser.add_argument(
        "--models",
        nargs="*",
        default=None,
        help="shipped model names in models.export_dir (default: sim.frontier_known.models)",
    )
    parser.add_argument("--out-raw", type=Path, required=True, help="one row per configuration and answer (CSV)")
    parser.add_argument("--out-csv", type=Path, required=True, help="the summary per answer (CSV)")
    parser.add_argument("overrides", nargs="*", help="Hydra overrides of config/hydra/structured.yaml")
    return parser


def main(argv: list[str]) -> int:
    args = _parser().parse_args(argv)
    from feeder.config import compose_config, parse_settings, pull_overrides

    args.models, args.overrides = pull_overrides(args.models, args.overrides)  # --models takes every word
    from feeder.io import write_csv

    settings = parse_settings(args.settings, "scene", "sim", "labels", "parts", "models")
    fk = check_frontier_known(settings)
    for flag, path in (("--dataset", args.dataset), ("--sim-dir", args.sim_dir), ("--parts-dir", args.parts_dir)):
        if not path.exists():
            raise FeederError(f"{flag} {path} is missing")
    for flag, path in (("--out-raw", args.out_raw), ("--out-csv", args.out_csv)):
        if path.suffix != ".csv":
            raise FeederError(f"{flag} {path}: the file to write ends in .csv")
    cfg = compose_config("structured", args.overrides)
    from feeder.bench.frontier import load_models
    from feeder.labels.dataset import load_dataset
    from feeder.learn.structured_data import structured_arrays
    from feeder.learn.structured_protocol import check_count, gated_neighbour

    check_count(cfg.seeds, "seeds")
    labels, bins = settings["labels"], int(settings["labels"]["bins"])
    names = fk["models"] if args.models is None else args.models
    models = load_models([m for m in names if m != ANALYTIC], bins, str(settings["models"]["export_dir"]))
    data = load_dataset(args.dataset)
    if "push_raw" not in data:
        raise FeederError(f"{args.dataset}: no push block (build the dataset with the part files)")
    made = json.loads(str(data["settings"]))
    for section in ("scene", "labels"):
        if made.get(section) != settings[section]:
            raise FeederError(
                f"{args.dataset} was made with another {section} than --settings gives: its labels and new "
                "simulations would not be comparable (run the bench with the study's own config)"
            )
    if (made.get("sim") or {}).get("yaw_sampling", "adaptive") != "adaptive":
        raise FeederError(
            f"{args.dataset}: its labels use the {made['sim']['yaw_sampling']} design; the bench simulates the "
            "adaptive design at each budget, so its answers would not be comparable"
        )
    if (made.get("sim") or {}).get("preset", settings["sim"]["preset"]) != settings["sim"]["preset"]:
        raise FeederError(
            f"{args.dataset} was simulated with preset {made['sim']['preset']}, --settings gives "
            f"{settings['sim']['preset']}: the new simulations would not be comparable"
        )
    say = lambda msg: print(f"feeder bench-frontier-known: {msg}", file=sys.stderr, flush=True)  # noqa: E731
    import torch

    torch.set_num_threads(int(cfg.train.threads))
    from feeder.learn.structured_calibration import calibration_network

    arrays = structured_arrays(
        data,
        cfg,
        args.sim_dir,
        args.parts_dir,
        args.features_dir,
        args.cache,
        say,
        calibration=calibration_network(cfg),
    )
    parts, cids, kept = arrays["part"], arrays["config_id"], arrays["kept"]
    train = arrays["split"] == "train"
    test = np.flatnonzero((arrays["split"] == "test") & kept)
    if test.size == 0 or not (train & kept).any():
        raise FeederError(f"{args.dataset}: no kept Test or training configuration to score")
    simulated = pick_rows(parts, cids, test, fk["configurations"], fk["seed"])
    timed = {int(i) for i in simulated}
    study = {"scene": settings["scene"], "labels": labels, "units": str(settings["parts"]["units"])}
    say(f"{test.size} Test configurations of {len(set(parts[test]))} parts, {simulated.size} of them simulated")

    answers: dict[str, dict[int, tuple]] = {}
    mean = arrays["pmf"][train & kept].mean(axis=0)
    answers[MEAN_PMF] = {int(i): (mean / mean.sum(), 0.0) for i in test}
    answers[ANALYTIC] = {
        int(i): (
            arrays["analytic"][i],
            analytic_seconds(args.parts_dir / f"{parts[i]}.stl", cids[i], study, fk["repeats"])
            if i in timed
            else np.nan,
        )
        for i in test
    }
    gates = [float(g) for g in cfg.neighbour.gates_deg]
    gated = gated_neighbour(arrays, train, test, gates)
    answers[NEIGHBOUR] = {int(i): (gated[n], answers[ANALYTIC][int(i)][1]) for n, i in enumerate(test)}
    data_rows = {(str(p), str(c)): n for n, (p, c) in enumerate(zip(data["part"], data["config_id"], strict=True))}
    d_rows = np.array([data_rows[(str(parts[i]), str(cids[i]))] for i in test])
    d_timed = {int(data_rows[(str(parts[i]), str(cids[i]))]) for i in timed}
    for name, model in models.items():
        got = model_answers(model, data, d_rows, args.parts_dir, d_timed, fk["repeats"], study)
        answers[name] = {int(i): got[int(j)] for i, j in zip(test, d_rows, strict=True)}
        say(f"{name}: answered")
    shipped = structured_fit(arrays, train, cfg, data, args.work_dir / FIT_FILE, say)
    answers[STRUCTURED] = structured_answers(
        shipped, arrays, test, train & kept, args.parts_dir, settings["scene"], timed, fk["repeats"]
    )
    say("structured predictor: answered")

    records = []
    for name, got in answers.items():
        for i in test:
            pmf, seconds = got[int(i)]
            base = {"config": f"{parts[i]}__{cids[i]}", "part": parts[i], "config_id": cids[i], "simulated": i in timed}
            records.append(
                base
                | {"answer": name, "kind": "predictor", "budget": 0, "simulations": 0, "cpu_s": seconds}
                | scores(pmf, arrays["pmf"][i])
            )
    for n, i in enumerate(simulated, 1):
        for budget in fk["budgets"]:
            path = args.work_dir / "sim" / str(parts[i]) / f"{cids[i]}__b{budget}.npz"
            pmf, cpu, sims = replicate_label(
                args.parts_dir / f"{parts[i]}.stl",
                str(cids[i]),
                budget,
                replicate_seed(fk["seed"], budget),
                settings,
                float(arrays["frame_deg"][i]),
                path,
            )
            got = {"circular_w1_deg": 180.0, "sup_cdf": 1.0} if pmf is None else scores(pmf, arrays["pmf"][i])
            records.append(
                {"config": f"{parts[i]}__{cids[i]}", "part": parts[i], "config_id": cids[i], "simulated": True}
                | {
                    "answer": f"simulate{budget}",
                    "kind": "simulate",
                    "budget": budget,
                    "simulations": sims,
                    "cpu_s": cpu,
                }
                | got
            )
        say(f"simulated {n}/{simulated.size} {parts[i]} {cids[i]}")
    raw = pd.DataFrame(records)
    write_csv(args.out_raw, raw)  # first: the raw rows survive a failing statistic
    table = summary(raw, fk["resamples"], fk["seed"])
    write_csv(args.out_csv, table)
    best = table[(table["configurations"] == "all")].sort_values("circular_w1_deg")
    say(
        "done; on the simulated configurations: "
        + ", ".join(f"{a} {w:.2f} deg" for a, w in zip(best["answer"], best["circular_w1_deg"], strict=True))
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
