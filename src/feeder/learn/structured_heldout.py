"""Deciding a change of the structured predictor on training rows alone (issue #39).

A change to how the protocol fits (``train.refit``, ``model.cross_only`` …) cannot be chosen on
the protocol's validation parts when it changes how they are used, and never on Test or Fences,
which are reported. These checks decide it on the training rows of the protocol's Main fits:

* in each Main fit, its own validation parts (those the real fit validates on) are held out
  (:func:`held_out`), or, as the Fences set is built, one two-fence type combination of each of
  its training parts (:func:`held_out_combinations`: the part's other rows stay in the fit);
* on the rest, the protocol's fit runs as usual once per arm (its own validation parts inside,
  the search, the seeds);
* the held-out parts are scored as known parts (:func:`score_held`): as Test rows (each reads its
  part's other held-out labels) and as Fences rows (the labels of its own fence-type combination
  hidden).

No Fences row and no locked part is read, and no row is scored by a fit whose Test set holds it;
but the Main repeats draw different Test sets, so a held-out row may be a Test row of another
repeat (as every protocol fit trains on other repeats' Test rows): :func:`with_test_flag` marks
them and :func:`arm_comparisons` compares with and without them.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pandas as pd

from feeder.errors import FeederError
from feeder.learn.splits import derived_seed, pick_parts, ranked_parts
from feeder.learn.structured_data import fence_key
from feeder.learn.structured_protocol import ENSEMBLE, STRUCTURED, paired_runs, pool_inputs, protocol_jobs, score_rows

SCORINGS = {"test": False, "fences": True}  # scored as a row of this set: hide its own fence-type combination?
MAIN = "main"


def held_out(arrays: dict, train: np.ndarray, cfg, key: str) -> tuple[np.ndarray, np.ndarray, set]:
    """(held-out mask, the rest of ``train``, the held-out parts): the validation parts the
    protocol's fit ``key`` on ``train`` draws (:func:`feeder.learn.structured_protocol.fit_protocol`)."""
    parts = pick_parts(
        arrays["part"][train], float(cfg.protocol.val_part_fraction), derived_seed(int(cfg.seed), key), "val"
    )
    held = train & np.isin(arrays["part"], list(parts))
    return held, train & ~held, parts


def held_out_combinations(arrays: dict, train: np.ndarray, cfg, key: str, fraction: float = 1.0):
    """(held-out mask, the rest of ``train``, {part: held combination}): for ``round(fraction ·
    n)`` of the ``n`` parts of ``train`` that have rows of a two-fence type combination there
    (ranked by sha256 of the seed derived from ``key``), every ``train`` row of one of those
    combinations, drawn per part from that seed. So a held row's part keeps its other combinations
    in the fit, as a Fences row's does (its reserved combination never in Main, the rest there)."""
    if not 0.0 < float(fraction) <= 1.0:
        raise FeederError(f"the held-out combinations' fraction of parts {fraction} must lie in (0, 1]")
    parts = np.asarray(arrays["part"]).astype(str)
    combos = np.array(["_".join(fence_key(c)[0]) for c in arrays["config_id"]])
    two = np.array(["none" not in fence_key(c)[0] for c in arrays["config_id"]])
    train = np.asarray(train, dtype=bool)
    seed = derived_seed(int(cfg.seed), key, "combinations")
    candidates = ranked_parts(parts[train & two], seed, "combinations")
    chosen: dict[str, str] = {}
    for p in candidates[: max(1, round(float(fraction) * len(candidates)))] if candidates else []:
        mine = sorted(set(combos[train & two & (parts == p)]))
        chosen[p] = mine[np.random.default_rng(derived_seed(seed, p)).integers(len(mine))]
    held = train & np.array([chosen.get(p) == c for p, c in zip(parts, combos, strict=True)])
    return held, train & ~held, chosen


def score_held(
    arrays: dict, cfg, fitted: dict, held, inner, scoring: str, index: int, prior_grids, pool=None
) -> pd.DataFrame:
    """The structured predictor's rows (seeds one by one and averaged) on the ``held`` rows, read as
    ``scoring`` (a key of :data:`SCORINGS`) from the labels of the rows ``pool`` (default: the held
    rows; as Fences rows never those of their own combination), with the inputs of ``cfg``;
    ``fitted`` has the protocol fit's ``fits``, ``x_mean``, ``x_sd`` and ``mean_pmf`` (a fit on
    ``inner``)."""
    a = pool_inputs(arrays, held if pool is None else pool, cfg, hide_same=SCORINGS[scoring])
    scaled = dict(a, x=(a["x"] - fitted["x_mean"]) / fitted["x_sd"])
    fake = {"fits": fitted["fits"], "scaled": scaled, "mean_pmf": fitted["mean_pmf"], "train": inner}
    rows = pd.DataFrame(score_rows(arrays, fake, np.flatnonzero(held), scoring, index, prior_grids))
    return rows[rows.predictor.isin([STRUCTURED, ENSEMBLE])]


_SHARED: dict = {}


def _forked(job: tuple) -> pd.DataFrame:
    check, arrays, cfg, prior_grids = (_SHARED[k] for k in ("check", "arrays", "cfg", "prior_grids"))
    return check(job, arrays, cfg, prior_grids)


def run_main_checks(arrays: dict, cfg, prior_grids, check: Callable) -> pd.DataFrame:
    """``check(job, arrays, cfg, prior_grids)`` (a DataFrame of rows) for every Main fit of the
    protocol, ``train.workers`` at once in forked processes, concatenated in job order."""
    from multiprocessing import get_context

    jobs = [job for job in protocol_jobs(arrays, cfg)[0] if job[0] == MAIN]
    _SHARED.update(check=check, arrays=arrays, cfg=cfg, prior_grids=prior_grids)
    with get_context("fork").Pool(min(int(cfg.train.workers), len(jobs))) as pool:
        return pd.concat(pool.map(_forked, jobs), ignore_index=True)


def with_test_flag(rows: pd.DataFrame, arrays: dict, cfg) -> pd.DataFrame:
    """``rows`` with ``in_a_test_set``: whether the configuration is in the Test set of any Main
    repeat (a held-out row is never in its own repeat's, but may be in another's)."""
    tests = set()
    for kind, _, _, _, scored in protocol_jobs(arrays, cfg)[0]:
        if kind == MAIN:
            idx = np.flatnonzero(scored["test"])
            tests |= set(zip(arrays["part"][idx], arrays["config_id"][idx], strict=True))
    keys = zip(rows.part.astype(str), rows.config_id.astype(str), strict=True)
    return rows.drop(columns=["held_out"], errors="ignore").assign(in_a_test_set=[k in tests for k in keys])


def arm_comparisons(
    rows: pd.DataFrame, bootstrap: dict, arm: str, against: str, scorings=tuple(SCORINGS)
) -> pd.DataFrame:
    """``arm`` against ``against`` (values of ``rows.arm``), paired per configuration
    (:func:`feeder.learn.structured_protocol.paired_runs`), for each scoring and for the seeds one
    by one and averaged where both have them: over every held-out row, and over those in no
    Main repeat's Test set; with the interval over configurations and over parts (``unit``)."""
    out = []
    for subset, mine in (("every held-out row", rows), ("in no Test set", rows[~rows.in_a_test_set])):
        for scoring in scorings:
            for model in (STRUCTURED, ENSEMBLE):
                for unit in ("configuration", "part"):
                    a, b = mine[mine.arm == arm], mine[mine.arm == against]
                    pair = paired_runs(a, b, scoring, model, bootstrap, by_part=unit == "part")
                    if pair is not None:  # e.g. no averaged seeds with one seed
                        out.append({"rows": subset, "scored_as": scoring, "model": model, "unit": unit, **pair})
    return pd.DataFrame(out)
