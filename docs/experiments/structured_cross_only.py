"""Would a Fences specialist answer Fences-like rows better? (issue #39)

A Fences row has no label of its own fence-type combination, only its part's labels in other
combinations (the cross neighbour). The protocol's network trains and is chosen on rows that
mostly do have such labels (about 88 % of a Main fit's training rows), and its early stopping and
search read validation rows as Test rows. ``model.cross_only: true`` is the other network: every
row, in training, validation and scoring, reads only its cross neighbours, so it is trained,
early-stopped and chosen for the situation of a Fences row. If it wins there, the shipped answer
would route the rows with no label of their own combination to it.

Test and Fences are reported, so neither can decide this; the check runs on the protocol's Main
fits' training rows alone (:mod:`feeder.learn.structured_heldout`): in each Main fit its own
validation parts are held out; on the rest the protocol's fit runs twice, as it is (``default``)
and with ``model.cross_only: true`` (``cross_only``), each with its own validation parts inside,
the search and three seeds; the held-out rows are scored as Fences rows (the labels of their own
combination hidden). The default network is also scored as Test rows, for the record.

Rule, fixed before the run (2026-11-28, stop 58): the specialist is adopted for rows with no label
of their own type combination if and only if, over the three Main fits' held-out rows scored as
Fences rows, its mean circular W1 (seeds one by one, as the protocol) is lower than the default
network's and the 95 % paired bootstrap interval over configurations excludes 0. A second network
in the shipped answer is a cost, so a point estimate alone does not pay for it.

    python docs/experiments/structured_cross_only.py [--combinations] results/datasets/dataset.npz \\
        results/sim results/features OUT_DIR [overrides]

(with ``OPENBLAS_CORETYPE=Haswell`` where the processor has AVX-512, as docs/testing.md says;
``train.workers`` fits at once) writes ``OUT_DIR/structured_cross_only_rows.csv`` (one row per
held-out configuration, arm, scoring and seed) and ``structured_cross_only.csv`` (the paired
comparisons), and prints the latter. With ``--from-rows ROWS.csv DATASET OUT_DIR`` it writes both
again from a run's rows, fitting nothing.

``--combinations`` (stop 59, after the Fences set disagreed with the check above): the held-out
rows are built as the Fences set is, not as unseen parts. In each Main fit, every training part
with two-fence rows loses one of its two-fence type combinations
(:func:`feeder.learn.structured_heldout.held_out_combinations`); the fit trains on the part's
other rows, and the held rows read them (never their own combination), as a Fences row reads
its part's Main rows. Scored as Fences rows only; tables ``structured_cross_only_combinations``
``{,_rows}.csv``. Its question, fixed before the run: does the specialist still win when the
held-out rows' parts are in the fit, as the Fences set's are? If its interval excludes 0 in the
specialist's favour again, the proxy's unseen parts do not explain the disagreement; if not,
they may, and this design replaces the parts design for Fences decisions. Either way the
specialist is not wired in by this run (it lost on the Fences set).
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
from omegaconf import OmegaConf

from feeder import io
from feeder.config import compose_config
from feeder.labels.dataset import load_dataset
from feeder.learn.prior import grids
from feeder.learn.structured_data import split_arrays, structured_arrays
from feeder.learn.structured_heldout import (
    arm_comparisons,
    held_out,
    held_out_combinations,
    run_main_checks,
    score_held,
    with_test_flag,
)
from feeder.learn.structured_protocol import fit_protocol

ARMS = {"default": False, "cross_only": True}  # arm: model.cross_only
# the inner fit's key (its validation parts and seeds): the stop-57 refit check's, so the default
# arm is that check's early-stopped fit and its rows can be compared with structured_refit_rows.csv
INNER_KEY = "{key}:refit-check"
COMBINATIONS = "--combinations"  # the held-out design of the Fences set (module doc)
COMBINATIONS_KEY = "{key}:combination-check"


def arm_cfg(cfg, on: bool):
    """``cfg`` with ``model.cross_only`` set to ``on``."""
    out = OmegaConf.create(OmegaConf.to_container(cfg, resolve=True))
    out.model.cross_only = bool(on)
    return out


def check_job(job: tuple, arrays: dict, cfg, prior_grids) -> pd.DataFrame:
    """One Main fit of the protocol: its validation parts held out, both arms fitted on the rest,
    the held-out rows scored as Fences rows (and, by the default arm, as Test rows)."""
    import torch

    torch.set_num_threads(int(cfg.train.threads))
    _, key, index, train, _ = job
    if _DESIGN["combinations"]:
        held, inner, held_parts = held_out_combinations(arrays, train, cfg, key)
        inner_key, pool, scorings = COMBINATIONS_KEY, train, {False: ("fences",), True: ("fences",)}
    else:
        held, inner, held_parts = held_out(arrays, train, cfg, key)
        inner_key, pool, scorings = INNER_KEY, None, {False: ("fences", "test"), True: ("fences",)}
    print(f"{key}: {len(held_parts)} parts held out ({int((held & arrays['kept']).sum())} kept rows)", flush=True)
    out = []
    for arm, on in ARMS.items():
        c = arm_cfg(cfg, on)
        f = fit_protocol(arrays, inner, c, inner_key.format(key=key), known=True)
        for scoring in scorings[on]:
            rows = score_held(arrays, c, f, held, inner, scoring, index, prior_grids, pool=pool)
            out.append(rows.assign(arm=arm))
        print(f"{key}: {arm} done ({f['choice']['kind']}, hidden {f['choice']['hidden']})", flush=True)
    return pd.concat(out, ignore_index=True)


_DESIGN = {"combinations": False}  # set by main before the forked checks


def main(argv: list[str]) -> int:
    _DESIGN["combinations"] = COMBINATIONS in argv
    argv = [a for a in argv if a != COMBINATIONS]
    name = "structured_cross_only_combinations" if _DESIGN["combinations"] else "structured_cross_only"
    if len(argv) < 4:
        raise SystemExit(__doc__)
    cfg_args = [*argv[4:], "protocol.fits=[main]"]
    if argv[0] == "--from-rows":  # the tables again from a run's rows, fitting nothing
        rows_path, dataset, out_dir = (Path(a) for a in argv[1:4])
        cfg = compose_config("structured", cfg_args)
        arrays, rows = split_arrays(load_dataset(dataset)), pd.read_csv(rows_path)
    else:
        dataset, sim_dir, features_dir, out_dir = (Path(a) for a in argv[:4])
        cfg = compose_config("structured", cfg_args)
        import torch

        torch.set_num_threads(int(cfg.train.threads))
        data = load_dataset(dataset)
        cache = dataset.with_name("structured_candidates.npz")
        arrays = structured_arrays(data, cfg, sim_dir, Path("parts"), features_dir, cache, print)
        rows = run_main_checks(arrays, cfg, grids(compose_config("train")["prior"]), check_job)
    rows = with_test_flag(rows, arrays, cfg)
    out_dir.mkdir(parents=True, exist_ok=True)
    io.write_csv(out_dir / f"{name}_rows.csv", rows)
    table = arm_comparisons(rows, dict(cfg.protocol.bootstrap), "cross_only", "default", scorings=("fences",))
    io.write_csv(out_dir / f"{name}.csv", table)
    print(table.to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
