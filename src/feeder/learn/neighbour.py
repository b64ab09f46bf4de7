"""The part's own neighbour: a known part at a new fence angle, predicted from its nearest simulated angle.

Issue #39's baseline for "known parts at new angles". Between two transitions of its basins a part's
PMF moves smoothly with the fence angle: the same basins, with masses and offsets that shift a
little. So the label of the same part under the same fence types at the nearest angles is already
a prediction, and a strong one on a grid as dense as the paper's (19 configurations per part).

* :func:`neighbour_index`: for each target row, the training row of the same part and the same
  fence-type combination at the least angle distance ``|Δθ1| + |Δθ2|`` (degrees; ``none`` has no
  angle), ties to the earlier row; -1 where the part has none.
* **neighbour**: that row's label as it is.
* **neighbour_shift** (angle-equivariant): that row's label rolled by the whole-bin shift that best
  carries the neighbour's analytic PMF onto the target's (least circular W1, within
  ``max_shift_deg``; ties to the smaller shift). The analytic push model knows how a resting
  orientation follows the fence angle; the simulated label supplies the masses. No label of a
  target row is read.

* **neighbour_gated**: the neighbour's label where it lies within ``gate`` degrees of angle distance,
  the analytic PMF elsewhere. ``gate`` is chosen from ``neighbour.gates_deg`` on the training rows
  alone (each training row predicted from its own nearest other training row; the least mean
  circular W1, ties to the smaller gate), never on the rows it is scored on.

Where a part has no training row of its combination, both fall back to the analytic PMF and the
row is counted (``fallback``). :func:`run_neighbour` scores them with the analytic PMF, the
training-mean PMF and the labels' own neighbour on the repeated Main splits of the structured
protocol (:mod:`feeder.learn.structured_protocol`), paired: the analytic PMF, the analytic prior
((σ, λ) fitted on the repeat's training rows, :mod:`feeder.learn.prior`) and the training-mean PMF.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from feeder.errors import FeederError
from feeder.learn.structured_data import fence_key

NEIGHBOUR = "neighbour"
SHIFTED = "neighbour_shift"
GATED = "neighbour_gated"
ANALYTIC = "analytic_pmf"
PRIOR = "analytic_prior"
MEAN = "mean_pmf"
PREDICTORS = (GATED, NEIGHBOUR, SHIFTED, ANALYTIC, PRIOR, MEAN)
# (predictor, baseline) pairs of the summary: the neighbours against every baseline, and each other
COMPARISONS = tuple((p, b) for p in (GATED, NEIGHBOUR, SHIFTED) for b in (ANALYTIC, PRIOR, MEAN)) + (
    (SHIFTED, NEIGHBOUR),
)


# ----------------------------------------------------------------------------------------------
# Pure functions
# ----------------------------------------------------------------------------------------------
def neighbour_index(parts, config_ids, train, rows) -> np.ndarray:
    """For each of ``rows``: the index of the nearest training row (``train``, a boolean mask) of
    the same part and type combination, by ``|Δθ1| + |Δθ2|``, ties to the lower index; -1 if none.
    A row is never its own neighbour."""
    parts = np.asarray(parts).astype(str)
    keys = [fence_key(c) for c in config_ids]
    train = np.asarray(train, dtype=bool)
    by_group: dict[tuple, list[int]] = {}
    for j in np.flatnonzero(train):
        by_group.setdefault((parts[j], keys[j][0]), []).append(int(j))
    out = np.full(len(rows), -1, dtype=np.int64)
    for n, i in enumerate(rows):
        pool = [j for j in by_group.get((parts[i], keys[i][0]), []) if j != i]
        if pool:
            angles = np.array([keys[j][1] for j in pool])
            dist = np.abs(angles - np.array(keys[i][1])).sum(axis=1)
            out[n] = pool[int(np.argmin(dist))]  # argmin: the first of equals, pools are in index order
    return out


def roll_pmf(pmf, shift_bins: int) -> np.ndarray:
    """``pmf`` moved ``shift_bins`` bins up the circle (wrapping at 360°)."""
    return np.roll(np.asarray(pmf, dtype=np.float64), int(shift_bins), axis=-1)


def best_shift(target, source, max_shift_bins: int) -> int:
    """The whole-bin shift ``s`` in ``[-max_shift_bins, max_shift_bins]`` whose ``roll(source, s)``
    lies nearest ``target`` by circular W1; ties go to the smaller ``|s|``, then the negative one.
    0 where either PMF holds no mass (an analytic model that jams every drop)."""
    from feeder.labels.metrics import circular_w1

    target, source = np.asarray(target, np.float64), np.asarray(source, np.float64)
    if not (target.sum() > 0 and source.sum() > 0):
        return 0
    m = int(max_shift_bins)
    shifts = np.array(sorted(range(-m, m + 1), key=lambda s: (abs(s), s)))
    rolled = np.stack([np.roll(source / source.sum(), s) for s in shifts])
    w1 = circular_w1(np.cumsum(target / target.sum()), np.cumsum(rolled, axis=1))
    return int(shifts[int(np.argmin(w1))])


def neighbour_pmfs(pmf, analytic, parts, config_ids, train, rows, max_shift_bins: int) -> dict:
    """The neighbour predictions of ``rows`` (module doc): ``neighbour`` and ``neighbour_shift``
    PMFs, each row's neighbour ``index`` (-1: none), its ``shift`` in bins and ``fallback``."""
    rows = np.asarray(rows, dtype=np.int64)
    idx = neighbour_index(parts, config_ids, train, rows)
    plain = np.asarray(analytic, np.float64)[rows].copy()
    shifted = plain.copy()
    shift = np.zeros(rows.size, dtype=np.int64)
    for n, (i, j) in enumerate(zip(rows, idx, strict=True)):
        if j < 0:
            continue
        shift[n] = best_shift(analytic[i], analytic[j], max_shift_bins)
        plain[n] = pmf[j]
        shifted[n] = roll_pmf(pmf[j], shift[n])
    return {NEIGHBOUR: plain, SHIFTED: shifted, "index": idx, "shift": shift, "fallback": idx < 0}


def angle_distance(config_a: str, config_b: str) -> float:
    """``|Δθ1| + |Δθ2|`` in degrees between two configurations (of one type combination)."""
    return float(np.abs(np.subtract(fence_key(config_a)[1], fence_key(config_b)[1])).sum())


def choose_gate(pmf, analytic, parts, config_ids, train, gates, rows=None) -> float:
    """The gate of ``gates`` (degrees) whose gated neighbour scores the least mean circular W1 on the
    training rows, each predicted from its nearest *other* training row; ties to the smaller gate.
    ``rows``: the rows scored (default: every training row), when ``train`` holds more neighbours."""
    from feeder.labels.metrics import circular_w1

    rows = np.flatnonzero(np.asarray(train, dtype=bool)) if rows is None else np.asarray(rows, dtype=np.int64)
    if not len(gates):
        raise FeederError("neighbour.gates_deg must hold at least one gate")
    idx = neighbour_index(parts, config_ids, train, rows)
    have = idx >= 0
    cdf = np.cumsum(pmf[rows], axis=1)
    w_nb = np.full(rows.size, np.inf)
    w_nb[have] = circular_w1(cdf[have], np.cumsum(pmf[idx[have]], axis=1))
    w_an = circular_w1(cdf, np.cumsum(analytic[rows], axis=1))
    dist = np.array(
        [angle_distance(config_ids[i], config_ids[j]) if j >= 0 else np.inf for i, j in zip(rows, idx, strict=True)]
    )
    scores = [float(np.where(dist <= g, w_nb, w_an).mean()) for g in sorted(gates)]
    return float(sorted(gates)[int(np.argmin(scores))])


# ----------------------------------------------------------------------------------------------
# The experiment
# ----------------------------------------------------------------------------------------------
def main_splits(split, repeats: int, test_fraction: float, seed: int) -> list[np.ndarray]:
    """Boolean Test masks of the repeated Main splits: repeat 0 the dataset's own Test rows, then
    ``test_fraction`` of the Main rows re-drawn per repeat (the structured protocol's splits)."""
    from feeder.learn.splits import derived_seed, resplit_rows

    split = np.asarray(split).astype(str)
    main = np.isin(split, ["train", "test"])
    out = [main & (split == "test")]
    for r in range(1, int(repeats)):
        test = np.zeros(split.size, dtype=bool)
        test[resplit_rows(np.flatnonzero(main), float(test_fraction), derived_seed(int(seed), "main", r))] = True
        out.append(test)
    return out


def score_repeats(
    data: dict, repeats: int, test_fraction: float, seed: int, max_shift_bins: int, prior_grids, gates=(0.0,)
) -> pd.DataFrame:
    """One row per Test configuration, repeat and predictor: circular W1 and the paper's R²,
    the neighbour, its angle distance and shift. Training rows are the repeat's other Main rows."""
    from feeder.labels.metrics import circular_w1, r2_cdf
    from feeder.learn.prior import blend, fit_blend

    pmf, analytic = np.asarray(data["pmf"], np.float64), np.asarray(data["pmf_analytic"], np.float64)
    parts, cids, split = (np.asarray(data[k]).astype(str) for k in ("part", "config_id", "split"))
    main = np.isin(split, ["train", "test"])
    cdf = np.cumsum(pmf, axis=1)
    out = []
    for r, test in enumerate(main_splits(split, repeats, test_fraction, seed)):
        train = main & ~test
        rows = np.flatnonzero(test)
        nb = neighbour_pmfs(pmf, analytic, parts, cids, train, rows, max_shift_bins)
        mean_pmf = pmf[train].mean(axis=0)
        prior = fit_blend(pmf, analytic, train, prior_grids.sigmas_bins, prior_grids.weights)
        gate = choose_gate(pmf, analytic, parts, cids, train, [float(g) for g in gates])
        dist = np.array(
            [np.nan if j < 0 else angle_distance(cids[i], cids[j]) for i, j in zip(rows, nb["index"], strict=True)]
        )
        near = (dist <= gate)[:, None]  # NaN (no neighbour) compares False: the analytic PMF
        preds = {
            GATED: np.where(near, nb[NEIGHBOUR], analytic[rows]),
            SHIFTED: nb[SHIFTED],
            NEIGHBOUR: nb[NEIGHBOUR],
            ANALYTIC: analytic[rows],
            PRIOR: blend(analytic[rows], mean_pmf, prior.sigma_bins, prior.weight),
            MEAN: np.broadcast_to(mean_pmf, (rows.size, pmf.shape[1])),
        }
        for name, p in preds.items():
            pc = np.cumsum(p, axis=1)
            cw1, r2 = circular_w1(cdf[rows], pc), r2_cdf(cdf[rows], pc)
            for n, i in enumerate(rows):
                out.append(
                    {
                        "repeat": r,
                        "part": parts[i],
                        "config_id": cids[i],
                        "predictor": name,
                        "cw1": float(cw1[n]),
                        "r2": float(r2[n]),
                        "neighbour": "" if nb["index"][n] < 0 else cids[nb["index"][n]],
                        "angle_distance_deg": dist[n],
                        "shift_deg": float(nb["shift"][n]) * 360.0 / pmf.shape[1],
                        "fallback": bool(nb["fallback"][n]),
                        "gate_deg": gate,
                    }
                )
    return pd.DataFrame(out)


def summary_table(long: pd.DataFrame, bootstrap: dict) -> pd.DataFrame:
    """Per comparison of ``COMPARISONS`` and metric: both means over configurations (each averaged
    over the repeats that hold it out), the predictor's median, and their paired difference with a
    bootstrap interval over configurations."""
    from feeder.learn.evaluate import paired_bootstrap, verdict

    per = {p: long[long.predictor == p].groupby(["part", "config_id"])[["cw1", "r2"]].mean() for p in PREDICTORS}
    fallback = long[long.predictor == SHIFTED].groupby(["part", "config_id"]).fallback.mean()
    rows = []
    for p, b in COMPARISONS:
        for metric, sign in (("cw1", -1), ("r2", 1)):
            mean, lo, hi = paired_bootstrap(
                (per[p][metric] - per[b][metric]).to_numpy(),
                bootstrap["resamples"],
                bootstrap["level"],
                bootstrap["seed"],
            )
            rows.append(
                {
                    "predictor": p,
                    "baseline": b,
                    "metric": metric,
                    "configurations": len(per[p]),
                    "repeats": int(long.repeat.nunique()),
                    "value": float(per[p][metric].mean()),
                    "median": float(per[p][metric].median()),
                    "baseline_value": float(per[b][metric].mean()),
                    "baseline_median": float(per[b][metric].median()),
                    "diff": mean,
                    "diff_low": lo,
                    "diff_high": hi,
                    "level": float(bootstrap["level"]),
                    "verdict": verdict(lo, hi, sign),
                    "fallback_share": float(fallback.mean()),
                }
            )
    return pd.DataFrame(rows)


def run_neighbour(data: dict, cfg, prior_grids) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The long rows and the summary of the neighbour experiment under ``cfg`` (the structured
    predictor's Hydra config: its ``protocol`` and ``neighbour`` nodes) and the analytic prior's
    ``prior_grids`` (:func:`feeder.learn.prior.grids`)."""
    if "pmf_analytic" not in data:
        raise FeederError("the dataset has no analytic PMFs (pmf_analytic): rebuild it with the part files")
    bins = np.asarray(data["pmf"]).shape[1]
    max_shift = float(cfg.neighbour.max_shift_deg)
    if not 0 <= max_shift <= 180:
        raise FeederError(f"neighbour.max_shift_deg must lie in [0, 180], got {max_shift}")
    if not (np.isin(np.asarray(data["split"]).astype(str), ["train", "test"]).any()):
        raise FeederError("the dataset has no Main rows (train/test)")
    long = score_repeats(
        data,
        int(cfg.protocol.main_repeats),
        float(cfg.protocol.test_fraction),
        int(cfg.seed),
        int(round(max_shift * bins / 360.0)),
        prior_grids,
        list(cfg.neighbour.gates_deg),
    )
    return long, summary_table(long, dict(cfg.protocol.bootstrap))


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="feeder neighbour",
        description=__doc__.split("\n")[0],
    )
    p.add_argument("--dataset", type=Path, required=True, help="results/datasets/dataset.npz")
    p.add_argument("--out-rows", type=Path, required=True, help="one row per configuration, repeat and predictor")
    p.add_argument("--out-csv", type=Path, required=True, help="the summary (paired against the analytic PMF)")
    p.add_argument("overrides", nargs="*", help="Hydra overrides of config/hydra/structured.yaml")
    return p


def main(argv: list[str]) -> int:
    from feeder import io
    from feeder.config import compose_config
    from feeder.labels.dataset import load_dataset
    from feeder.learn.prior import grids

    args = _parser().parse_args(argv)
    cfg = compose_config("structured", args.overrides)
    prior_grids = grids(compose_config("train")["prior"])
    long, table = run_neighbour(load_dataset(args.dataset), cfg, prior_grids)
    io.write_csv(args.out_rows, long)
    io.write_csv(args.out_csv, table)
    cols = ["predictor", "baseline", "value", "baseline_value", "diff", "diff_low", "diff_high", "verdict"]
    print(table.loc[table.metric == "cw1", cols].to_string(index=False))
    return 0
