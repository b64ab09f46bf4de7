"""The analytic model calibrated on a known part's own labels (issue #39, known parts and Fences)

Every change to the analytic model measured in stops 70-71 (``fence_turns.py``: friction scaled
where the part turns, a moment turn rate, basin boundaries turned, a contact patch on rolling arcs,
a steep curved fence's grazers pushed or swung) fixed the parts it was built for and broke others
by about as much, so none won on the library. For a part the study has labelled, its own labels
can say which of them is its physics. This script measures that, with nothing fitted but a choice:

for each Main fit of ``feeder structured`` (repeat ``r``) and each part, the *mode* (one of
``fence_turns.py``'s, ``base`` the default model) whose analytic PMF has the lowest mean circular
W1 over the part's training rows of that fit (kept, not locked, not in that repeat's Test rows,
not in Fences) answers the part's scored rows. A *rule* is a family of modes and a margin: the
chosen mode replaces ``base`` only where it beats it on the part's training rows by at least the
margin (degrees).

The rule is chosen on training rows alone, by scoring each rule as the sets will use it:
``loo`` (Test: each training row answered by the mode chosen on the part's other training rows)
and ``loco`` (Fences: each training row answered by the mode chosen on the part's training rows
of other fence-type combinations). The chosen rules are then scored once on the protocol's own
Test and Fences rows (``structured_rows.csv``), paired by configuration (averaged over repeats,
95 % bootstrap over configurations as ``feeder structured`` does) with the analytic PMF of the
same table (``base``) and with the structured predictor's shipped answer; the summary also gives
each part's mean difference and its interval with parts resampled (a part's configurations are not
independent of each other).

``analytic`` is this table's analytic PMF; ``analytic_protocol`` the one ``feeder structured``
scored (the dataset's, built with the label smoothing: up to 0.8 deg apart per configuration, 0.2
on average), which ``gated_calibrated`` (the gated neighbour of the protocol, with the calibrated
model where it falls back to the analytic PMF) is compared with.

    python docs/experiments/part_calibration.py results/tables/fence_turns_pmf.csv.gz \
        results/tables/part_calibration_pmf.csv.gz --rows results/tables/structured_rows.csv \
        --out results/tables/part_calibration

Writes ``<out>_rules.csv`` (each rule's training-row scores), ``<out>_rows.csv`` (every scored
row: the chosen mode and its circular W1 beside the structured and analytic ones),
``<out>_summary.csv`` and ``<out>_ranked.csv`` (the Test rule's family cut to its k most picked
modes, scored on training rows: what a pipeline would need to compute). About 5 minutes; reads only
the tables.
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads (feeder/__init__.py)

# isort: on
import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from feeder.io import write_csv
from feeder.learn.evaluate import fence_types, paired_bootstrap

BASE = "base"
MARGINS_DEG = (0.0, 0.5, 1.0, 2.0, 4.0)
# the mode families a rule chooses within (base is in every one)
FAMILIES = {
    "all": None,  # every mode of the table
    # analytic_distribution's own arguments: what feeder.mechanics can answer with as it is
    "args": ("graze:", "moment:", "bound:", "mu:", "budget:", "noexit", "nojams", "ride:"),
    "friction": ("mu:",),
    "graze": ("graze:",),
    "patch": ("patch:", "arcpatch:"),
    "turn": ("push:", "turn:", "moment:"),
}
COMPARISONS = (
    ("calibrated", "analytic"),
    ("calibrated", "structured"),
    ("structured", "analytic"),
    ("gated_calibrated", "structured"),
    ("gated_calibrated", "gated"),
    ("gated_calibrated", "analytic_protocol"),
)
FELL_BACK_DEG = 1e-9  # a gated neighbour's W1 this close to the analytic PMF's: it answered with the latter
BOOTSTRAP = dict(resamples=10000, level=0.95, seed=0)
SETS = ("test", "fences")


def load(pmf_csvs: list[Path], rows_csv: Path) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(circular W1 per configuration × mode, indexed by part and config_id, from every raw table
    of ``fence_turns.py pmf``; the structured protocol's kept rows)."""
    raw = pd.concat([pd.read_csv(p) for p in pmf_csvs], ignore_index=True).drop_duplicates(
        ["mode", "part", "config_id"]
    )
    w1 = raw.pivot_table(index=["part", "config_id"], columns="mode", values="circular_w1_deg")
    if w1.isna().any().any():
        raise SystemExit("the raw tables do not hold every mode for every configuration")
    rows = pd.read_csv(rows_csv)
    return w1, rows[rows.kept]


def training_sets(w1: pd.DataFrame, rows: pd.DataFrame) -> dict[int, pd.Index]:
    """Per Main repeat, the (part, config_id) the fit trains on among the table's configurations:
    not locked, not that repeat's Test rows, not Fences."""
    locked = set(rows[rows.experiment == "unseen_locked"].part)
    fences = set(zip(*[rows[rows.experiment == "fences"][c] for c in ("part", "config_id")]))
    out = {}
    for r in sorted(rows[rows.experiment == "test"].repeat.unique()):
        t = rows[(rows.experiment == "test") & (rows.repeat == r)]
        held = fences | set(zip(t.part, t.config_id))
        keep = [k for k in w1.index if k[0] not in locked and k not in held]
        out[int(r)] = pd.MultiIndex.from_tuples(keep, names=w1.index.names)
    return out


def family_modes(w1: pd.DataFrame, family: str) -> list[str]:
    prefixes = FAMILIES[family]
    if prefixes is None:
        return list(w1.columns)
    return [BASE, *[m for m in w1.columns if m != BASE and m.startswith(prefixes)]]


def choose(train_w1: pd.DataFrame, modes: list[str], margin: float) -> str:
    """The mode of ``modes`` with the least mean W1 over ``train_w1``'s rows, ``base`` unless it
    beats ``base`` by at least ``margin``; ``base`` with no rows."""
    if train_w1.empty:
        return BASE
    mean = train_w1[modes].mean()
    best = str(mean.idxmin())
    return best if mean[BASE] - mean[best] >= margin else BASE


def rule_scores(w1: pd.DataFrame, train: dict[int, pd.Index], modes: list[str], margin: float) -> dict:
    """Mean W1 on training rows answered under ``loo`` and ``loco`` (module doc), over repeats,
    beside ``base``'s on the same rows."""
    out = {"loo": [], "loco": [], "base": []}
    for idx in train.values():
        t = w1.loc[idx]
        types = pd.Series([fence_types(c) for c in t.index.get_level_values("config_id")], index=t.index)
        for _part, g in t.groupby(level="part"):
            for key in g.index:
                out["base"].append(g.loc[key, BASE])
                out["loo"].append(g.loc[key, choose(g.drop(index=key), modes, margin)])
                other = g[types.loc[g.index] != types.loc[key]]
                out["loco"].append(g.loc[key, choose(other, modes, margin)])
    return {k: float(np.mean(v)) for k, v in out.items()}


def ranked_families(w1: pd.DataFrame, train: dict[int, pd.Index], family: str, margin: float) -> pd.DataFrame:
    """How few modes do as well (training rows only): the modes of ``family`` ranked by how often
    the rule picks them for a part × repeat on all its training rows, and the rule's training-row
    scores with ``base`` and the first k of them, for every k."""
    modes = family_modes(w1, family)
    picks = pd.Series(
        [choose(g, modes, margin) for idx in train.values() for _, g in w1.loc[idx].groupby(level="part")]
    ).value_counts()
    order = [m for m in picks.index if m != BASE]
    out = []
    for k in range(1, len(order) + 1):
        s = rule_scores(w1, train, [BASE, *order[:k]], margin)
        out.append(dict(k=k, added=order[k - 1], picks=int(picks[order[k - 1]]), loo=s["loo"], loco=s["loco"]))
    return pd.DataFrame(out)


def scored_rows(w1: pd.DataFrame, rows: pd.DataFrame, train: dict[int, pd.Index], rules: dict) -> pd.DataFrame:
    """Every protocol row of SETS with the analytic (``base``) W1, the structured ensemble's and
    the W1 of the mode its set's rule chooses on the part's training rows of that repeat."""
    key = ["experiment", "repeat", "part", "config_id"]
    ens, gated, protocol_analytic = (
        rows[rows.predictor == p].set_index(key).cw1 for p in ("structured_ensemble", "neighbour_gated", "analytic_pmf")
    )
    out = []
    for exp in SETS:
        modes, margin = rules[exp]
        a = rows[(rows.experiment == exp) & (rows.predictor == "analytic_pmf")]
        for _, row in a.iterrows():
            idx = train[int(row["repeat"])]
            mine = w1.loc[idx[idx.get_level_values("part") == row.part]]
            mode = choose(mine, modes, margin)
            k = (exp, row["repeat"], row.part, row.config_id)
            analytic, calibrated = w1.loc[(row.part, row.config_id), BASE], w1.loc[(row.part, row.config_id), mode]
            # the gated neighbour answers with the analytic PMF where no label lies within its gate
            fell_back = abs(gated.loc[k] - protocol_analytic.loc[k]) < FELL_BACK_DEG
            out.append(
                dict(
                    experiment=exp,
                    repeat=int(row["repeat"]),
                    part=row.part,
                    config_id=row.config_id,
                    mode=mode,
                    analytic=analytic,
                    calibrated=calibrated,
                    structured=ens.loc[k],
                    gated=gated.loc[k],
                    analytic_protocol=protocol_analytic.loc[k],
                    gated_fell_back=fell_back,
                    # the gated neighbour with the calibrated model as its fallback: the protocol's
                    # analytic W1 moved by the chosen mode's difference from base on this table
                    gated_calibrated=protocol_analytic.loc[k] + calibrated - analytic if fell_back else gated.loc[k],
                )
            )
    return pd.DataFrame(out)


def summary(scored: pd.DataFrame, comparisons=COMPARISONS) -> pd.DataFrame:
    """Per set and (model, baseline) pair of W1 columns of ``scored``: both means and their paired
    difference, bootstrapped over configurations (each averaged over its repeats) and over parts."""
    out = []
    columns = sorted({c for pair in comparisons for c in pair})
    for exp, d in scored.groupby("experiment", sort=False):
        per = d.groupby(["part", "config_id"])[columns].mean()
        by_part = per.groupby(level="part").mean()
        for model, base in comparisons:
            diff, lo, hi = paired_bootstrap((per[model] - per[base]).to_numpy(), **BOOTSTRAP)
            _, lo_p, hi_p = paired_bootstrap((by_part[model] - by_part[base]).to_numpy(), **BOOTSTRAP)
            out.append(
                dict(
                    experiment=exp,
                    model=model,
                    baseline=base,
                    configurations=len(per),
                    parts=per.index.get_level_values("part").nunique(),
                    model_w1=per[model].mean(),
                    baseline_w1=per[base].mean(),
                    diff=diff,
                    diff_low=lo,
                    diff_high=hi,
                    part_mean_diff=float((by_part[model] - by_part[base]).mean()),
                    part_low=lo_p,
                    part_high=hi_p,
                )
            )
    return pd.DataFrame(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("pmf_csvs", type=Path, nargs="+", help="raw tables of fence_turns.py pmf")
    ap.add_argument("--rows", type=Path, required=True, help="structured_rows.csv of feeder structured")
    ap.add_argument("--out", required=True, help="prefix of the three tables written")
    args = ap.parse_args(argv)
    w1, rows = load(args.pmf_csvs, args.rows)
    train = training_sets(w1, rows)
    table = []
    for family in FAMILIES:
        modes = family_modes(w1, family)
        for margin in MARGINS_DEG:
            s = rule_scores(w1, train, modes, margin)
            table.append(dict(family=family, margin_deg=margin, **s))
            print(table[-1], file=sys.stderr)
    rules_df = pd.DataFrame(table)
    # Test answers a part's new angle (loo); Fences a new fence-type combination (loco)
    best = {
        "test": rules_df.loc[rules_df.loo.idxmin()],
        "fences": rules_df.loc[rules_df.loco.idxmin()],
    }
    rules = {k: (family_modes(w1, v.family), float(v.margin_deg)) for k, v in best.items()}
    rules_df["chosen_for"] = [
        ",".join(k for k, v in best.items() if v.family == r.family and v.margin_deg == r.margin_deg)
        for r in rules_df.itertuples()
    ]
    scored = scored_rows(w1, rows, train, rules)
    summ = summary(scored)
    ranked = ranked_families(w1, train, best["test"].family, float(best["test"].margin_deg))
    write_csv(f"{args.out}_ranked.csv", ranked)
    write_csv(f"{args.out}_rules.csv", rules_df)
    write_csv(f"{args.out}_rows.csv", scored)
    write_csv(f"{args.out}_summary.csv", summ)
    print(rules_df.to_string(index=False))
    print(summ.to_string(index=False))
    print(scored.groupby(["experiment", "mode"]).size().to_string())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
