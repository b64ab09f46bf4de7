"""Should each fit train again on its validation parts after early stopping? (issue #39)

``train.refit: true`` trains each early-stopped seed again on the fit and validation rows together,
for the steps early stopping kept it, from the same initial weights. The protocol's validation
parts are then spent, and Test and Fences are what we report, so neither can decide it. This
check decides it on the training rows of the protocol's Main fits alone:

- in each Main fit, its own validation parts (the 20 % the real fit validates on) are held out;
- on the rest the protocol's fit runs as usual (its own validation parts inside them, the search,
  three seeds), with and without the refit (the same early-stopped seeds: ``fit_protocol``'s
  ``early``);
- the held-out parts are scored as the protocol scores a validation row of a known part: each
  row reads its part's other held-out rows (as a Test row reads its part's labels: written
  with ``experiment`` ``test``), and once more with the labels of its own fence-type combination
  hidden (as a Fences row: ``fences``). No Fences row and no locked part is read, and no row is
  scored by a fit whose Test set holds it; but the three Main repeats draw different Test sets,
  so a held-out row may be a Test row of another repeat (as every fit of the protocol trains on
  other repeats' Test rows). The rows file flags those (``in_a_test_set``), and the comparisons
  are also given without them.

Rule, fixed before the run (2026-11-28): the default becomes ``train.refit: true`` if and only if
the refit's mean circular W1 (seeds scored one by one, as the protocol) is lower than without it
on both scorings, over the three Main fits' held-out rows. The 95 % paired bootstrap intervals
over configurations are reported beside it; the rule is the point estimate, as the protocol's own
search chooses.

    python docs/experiments/structured_refit.py results/datasets/dataset.npz results/sim \\
        results/features OUT_DIR [overrides]

(run it with ``OPENBLAS_CORETYPE=Haswell`` where the processor has AVX-512: it imports numpy
before feeder, which otherwise sets that; docs/testing.md; ``train.workers`` fits at once) writes
``OUT_DIR/structured_refit_rows.csv`` (one row per held-out configuration, arm, scoring and seed)
and ``structured_refit.csv`` (the paired comparisons), and prints the latter. With
``--from-rows ROWS.csv DATASET OUT_DIR`` it writes both again from a run's rows, fitting nothing.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd

from feeder import io
from feeder.config import compose_config
from feeder.labels.dataset import load_dataset
from feeder.learn.prior import grids
from feeder.learn.structured_data import split_arrays, structured_arrays
from feeder.learn.structured_heldout import (
    SCORINGS,
    arm_comparisons,
    held_out,
    run_main_checks,
    score_held,
    with_test_flag,
)
from feeder.learn.structured_protocol import fit_protocol


def check_job(job: tuple, arrays: dict, cfg, prior_grids) -> pd.DataFrame:
    """One Main fit of the protocol: its validation parts held out, the fit on the rest with and
    without the refit, the held-out rows scored both ways."""
    import torch

    torch.set_num_threads(int(cfg.train.threads))
    _, key, index, train, _ = job
    held, inner, held_parts = held_out(arrays, train, cfg, key)
    print(f"{key}: {len(held_parts)} parts held out ({int((held & arrays['kept']).sum())} kept rows)", flush=True)
    f = fit_protocol(arrays, inner, cfg, f"{key}:refit-check", known=True)
    out = []
    for scoring in SCORINGS:
        for arm, fitted in (("early", f["early"]), ("refit", f)):
            out.append(score_held(arrays, cfg, fitted, held, inner, scoring, index, prior_grids).assign(arm=arm))
    print(f"{key}: done ({f['choice']['kind']}, hidden {f['choice']['hidden']})", flush=True)
    return pd.concat(out, ignore_index=True)


def main(argv: list[str]) -> int:
    if len(argv) < 4:
        raise SystemExit(__doc__)
    if argv[0] == "--from-rows":  # the tables again from a run's rows, fitting nothing
        rows_path, dataset, out_dir = (Path(a) for a in argv[1:4])
        cfg = compose_config("structured", [*argv[4:], "protocol.fits=[main]", "train.refit=true"])
        arrays, rows = split_arrays(load_dataset(dataset)), pd.read_csv(rows_path)
    else:
        dataset, sim_dir, features_dir, out_dir = (Path(a) for a in argv[:4])
        cfg = compose_config("structured", [*argv[4:], "protocol.fits=[main]", "train.refit=true"])
        import torch

        torch.set_num_threads(int(cfg.train.threads))
        data = load_dataset(dataset)
        cache = dataset.with_name("structured_candidates.npz")
        arrays = structured_arrays(data, cfg, sim_dir, Path("parts"), features_dir, cache, print)
        rows = run_main_checks(arrays, cfg, grids(compose_config("train")["prior"]), check_job)
    rows = with_test_flag(rows, arrays, cfg)
    out_dir.mkdir(parents=True, exist_ok=True)
    io.write_csv(out_dir / "structured_refit_rows.csv", rows)
    table = arm_comparisons(rows, dict(cfg.protocol.bootstrap), "refit", "early")
    io.write_csv(out_dir / "structured_refit.csv", table)
    print(table.to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
