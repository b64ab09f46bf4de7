"""How fast a trained model answers for a part: ``feeder bench-predict``.

    feeder bench-predict --model results/models/m3 [--parts parts/a.stl ...] [--repeats 7] \\
        [--cold-repeats 5] --out results/tables/predict_speed.csv \\
        --summary results/tables/predict_speed_summary.csv

Issue 22 asks ``feeder predict`` for a part's features in at most 200 ms, then at most 5 ms per
fence configuration, so that ``feeder recommend`` ranks the study's whole fence grid in about a
second. For each part (``--parts``, default ``DEFAULT_PARTS`` of ``parts/``) this measures,
``--repeats`` times in this process after one untimed warm-up (so no import is counted):

* ``features``: the 45 DFT features and the frame of the part from its file
  (:func:`feeder.learn.predict.part_vector`, what ``predict`` and ``recommend`` run);
* ``symmetry``: the part's rotational order from its STL (``recommend --symmetry auto``);
* ``config``: the prediction of one fence configuration (``--loc1``, ``--loc2``;
  :func:`feeder.learn.predict.predict_frame`), the features given;
* ``grid``: the ranking of every configuration of the study's fence grid (``fences`` of the
  config, or ``--settings``/``--configfile``; :func:`feeder.learn.recommend.rank`: one batched
  forward pass), the features given;

and ``--cold-repeats`` times in a fresh interpreter (:mod:`feeder.bench.predict_probe`, the steps
of ``feeder predict`` in a new process): ``import`` (the predict command's module), ``model_load``
(the weights, read and answered in numpy: :mod:`feeder.learn.inference`), ``features_cold`` (the
process's first features: the feature path's lazy imports plus the computation), ``config_cold``
(the first configuration: the label and fence modules' imports plus the network) and ``process``
(the child process's wall time from start to exit, interpreter start-up included). Start-up is
therefore kept apart from the features and from the work per configuration. Each cold repeat
also runs ``feeder predict`` itself for one configuration (``--loc1``, ``--loc2``) as a user
does, ``python -m feeder predict ... --out FILE``, and times its wall clock from start to exit:
``predict`` (issue 36: at most 1 s). The fresh processes are ``--interval`` seconds apart, so
that one run's exit (its pages, the disk cache) does not lean on the next.

``--out`` keeps every timing (``part, stage, repeat, configs, ms``; ``configs``: the configurations
a timing covers, 0 for none), so other statistics need no rerun. ``--summary`` has, per part and
stage and over all parts (part ``all``): the repeats, the median, minimum and maximum in ms, the
median per configuration (``config``, ``grid``), and the goal of issue 22 (``goal_ms``: features
200 ms; a configuration 5 ms; the grid 1 s) with whether the median meets it (``meets_goal``).
Timings on a machine busy with other jobs spread wider; the minimum is the least disturbed one.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from feeder.errors import FeederError

if TYPE_CHECKING:  # pandas and numpy load inside the functions: the workflow imports DEFAULT_PARTS
    import pandas as pd

DEFAULT_PARTS = ("rect-a2", "crescent-a", "gear20-a", "blob-d", "keyhole-a")  # in --parts-dir
DEFAULT_REPEATS = 7
DEFAULT_COLD_REPEATS = 5
DEFAULT_INTERVAL_S = 1.0  # seconds between two fresh processes
MIN_REPEATS = 1
DEFAULT_LOC1 = "straight:30"
DEFAULT_LOC2 = "none"
# recommend's window for the grid ranking (its cost does not depend on them)
RANK_TARGET_DEG = 0.0
RANK_TOLERANCE_DEG = 10.0
# issue 22's goals
FEATURES_GOAL_MS = 200.0
CONFIG_GOAL_MS = 5.0
GRID_GOAL_MS = 1000.0
PREDICT_GOAL_MS = 1000.0  # issue 36: a fresh `feeder predict` of one configuration
GOALS_MS = {
    "features": FEATURES_GOAL_MS,
    "features_cold": FEATURES_GOAL_MS,
    "config": CONFIG_GOAL_MS,
    "grid": GRID_GOAL_MS,
    "predict": PREDICT_GOAL_MS,
}
WARM_STAGES = ("features", "symmetry", "config", "grid")
PROBE_STAGES = ("import", "model_load", "features_cold", "config_cold", "process")
COLD_STAGES = (*PROBE_STAGES, "predict")
RAW_COLUMNS = ["part", "stage", "repeat", "configs", "ms"]
SUMMARY_COLUMNS = [
    "part",
    "stage",
    "repeats",
    "configs",
    "median_ms",
    "min_ms",
    "max_ms",
    "median_ms_per_config",
    "goal_ms",
    "meets_goal",
]
ALL_PARTS = "all"
PROBE_TIMEOUT_S = 600


def _timed(fn) -> tuple[float, object]:
    start = time.perf_counter()
    out = fn()
    return 1e3 * (time.perf_counter() - start), out


def warm_timings(model, part: Path, config_ids: list[str], loc1: str, loc2: str, repeats: int) -> list[dict]:
    """``repeats`` timings of each warm stage for one part (one untimed warm-up call first)."""
    from feeder.learn.predict import part_vector, predict_frame
    from feeder.learn.recommend import rank, symmetry_order

    part_raw, frame_deg = part_vector(part, None)
    order = symmetry_order("auto", part)
    stages = {
        "features": (0, lambda: part_vector(part, None)),
        "symmetry": (0, lambda: symmetry_order("auto", part)),
        "config": (1, lambda: predict_frame(model, part_raw, loc1, loc2, frame_deg)),
        "grid": (
            len(config_ids),
            lambda: rank(model, part_raw, frame_deg, config_ids, RANK_TARGET_DEG, RANK_TOLERANCE_DEG, order),
        ),
    }
    rows = []
    for stage, (configs, fn) in stages.items():
        fn()  # warm-up: first-call imports and caches are not the stage's cost
        for r in range(repeats):
            ms, _ = _timed(fn)
            rows.append({"part": part.stem, "stage": stage, "repeat": r, "configs": configs, "ms": ms})
    return rows


def _fresh_run(cmd: list[str], what: str) -> tuple[float, str]:
    """(wall ms from start to exit, stdout) of one fresh process; a one-line error if it fails."""
    start = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=PROBE_TIMEOUT_S)
    wall = 1e3 * (time.perf_counter() - start)
    if proc.returncode != 0:
        last = (proc.stderr.strip().splitlines() or ["no output"])[-1]
        raise FeederError(f"{what} failed: {last}")
    return wall, proc.stdout


def cold_timings(
    model_dir: Path, part: Path, loc1: str, loc2: str, repeats: int, interval_s: float = DEFAULT_INTERVAL_S
) -> list[dict]:
    """``repeats`` fresh-interpreter runs for one part, ``interval_s`` apart: the steps of
    :mod:`feeder.bench.predict_probe`, then ``feeder predict`` itself (stage ``predict``)."""
    import tempfile

    from feeder.bench import predict_probe

    probe = [sys.executable, predict_probe.__file__, str(model_dir), str(part), loc1, loc2]
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-predict-") as tmp:
        predict = [sys.executable, "-m", "feeder", "predict", "--model", str(model_dir), "--part", str(part)]
        predict += ["--loc1", loc1, "--loc2", loc2, "--out", str(Path(tmp) / "pmf.csv")]
        for r in range(repeats):
            time.sleep(interval_s if r else 0.0)
            wall, out = _fresh_run(probe, f"cold run of {part.name}")
            time.sleep(interval_s)
            predict_ms, _ = _fresh_run(predict, f"feeder predict of {part.name}")
            stages = {**json.loads(out.strip().splitlines()[-1]), "process": wall, "predict": predict_ms}
            rows += _cold_rows(part, r, stages)
    return rows


def _cold_rows(part: Path, repeat: int, stages: dict) -> list[dict]:
    """One cold repeat's timings as rows (:data:`RAW_COLUMNS`)."""
    rows = []
    for stage in COLD_STAGES:
        configs = 1 if stage in ("config_cold", "predict") else 0
        rows.append({"part": part.stem, "stage": stage, "repeat": repeat, "configs": configs, "ms": stages[stage]})
    return rows


def summarise(raw: pd.DataFrame) -> pd.DataFrame:
    """Per part and stage, then per stage over all parts (part ``all``): repeats, median, minimum
    and maximum (ms), the median per configuration, and the goal with whether the median meets it."""
    import numpy as np
    import pandas as pd

    stages = [s for s in WARM_STAGES + COLD_STAGES if s in set(raw["stage"])]
    groups = [
        (part, stage, raw[(raw["part"] == part) & (raw["stage"] == stage)])
        for part in raw["part"].unique()
        for stage in stages
    ]
    groups += [(ALL_PARTS, stage, raw[raw["stage"] == stage]) for stage in stages]
    rows = []
    for part, stage, group in groups:
        if group.empty:
            continue
        ms = group["ms"].to_numpy(dtype=np.float64)
        configs = int(group["configs"].max())
        median = float(np.median(ms))
        goal = GOALS_MS.get(stage)
        rows.append(
            {
                "part": part,
                "stage": stage,
                "repeats": len(ms),
                "configs": configs,
                "median_ms": median,
                "min_ms": float(ms.min()),
                "max_ms": float(ms.max()),
                "median_ms_per_config": median / configs if configs else np.nan,
                "goal_ms": np.nan if goal is None else goal,
                "meets_goal": pd.NA if goal is None else bool(median <= goal),
            }
        )
    return pd.DataFrame(rows, columns=SUMMARY_COLUMNS)


def run(
    model_dir: Path,
    parts: list[Path],
    fences: dict,
    loc1: str = DEFAULT_LOC1,
    loc2: str = DEFAULT_LOC2,
    repeats: int = DEFAULT_REPEATS,
    cold_repeats: int = DEFAULT_COLD_REPEATS,
    progress=None,
    interval_s: float = DEFAULT_INTERVAL_S,
) -> pd.DataFrame:
    """Every timing (:data:`RAW_COLUMNS`) of the parts, warm stages then cold ones."""
    import pandas as pd

    from feeder.lane.fences import parse_location
    from feeder.learn.predict import load_model
    from feeder.learn.recommend import grid_configurations

    if repeats < MIN_REPEATS or cold_repeats < 0:
        raise FeederError(f"--repeats must be at least {MIN_REPEATS} and --cold-repeats at least 0")
    if not interval_s >= 0:
        raise FeederError(f"--interval must be 0 seconds or more, got {interval_s!r}")
    if not parts:
        raise FeederError("no parts to time")
    for part in parts:
        if not part.is_file():
            raise FeederError(f"part file {part} is missing")
    parse_location(loc1), parse_location(loc2)
    config_ids = grid_configurations(fences)
    model = load_model(model_dir)
    rows = []
    for part in parts:
        rows += warm_timings(model, part, config_ids, loc1, loc2, repeats)
        rows += cold_timings(model_dir, part, loc1, loc2, cold_repeats, interval_s)
        if progress is not None:
            print(f"bench-predict: {part.name} done", file=progress)
    return pd.DataFrame(rows, columns=RAW_COLUMNS)


def main(argv: list[str]) -> int:
    from feeder.bench.accuracy import add_config_source, config_from_args
    from feeder.io import write_csv

    ap = argparse.ArgumentParser(
        prog="feeder bench-predict", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--model", type=Path, required=True, help="trained model directory (as for feeder predict)")
    ap.add_argument("--parts", type=Path, nargs="+", help="part files (.stl); default: DEFAULT_PARTS in --parts-dir")
    ap.add_argument("--parts-dir", type=Path, default=Path("parts"), help="where the default parts are (the project's)")
    ap.add_argument("--loc1", default=DEFAULT_LOC1, help="fence at location 1 of the one-configuration timing")
    ap.add_argument("--loc2", default=DEFAULT_LOC2, help="fence at location 2 of the one-configuration timing")
    ap.add_argument("--repeats", type=int, default=DEFAULT_REPEATS, help="timings of each stage in this process")
    ap.add_argument("--cold-repeats", type=int, default=DEFAULT_COLD_REPEATS, help="fresh-interpreter runs a part")
    ap.add_argument("--interval", type=float, default=DEFAULT_INTERVAL_S, help="seconds between two fresh processes")
    add_config_source(ap, "fences")
    ap.add_argument("--out", type=Path, required=True, help="CSV of every timing")
    ap.add_argument("--summary", type=Path, required=True, help="CSV of the statistics")
    args = ap.parse_args(argv)
    cfg = config_from_args(args)
    if "fences" not in cfg:
        raise FeederError("settings lack section fences")
    from feeder.config import project_path

    parts = args.parts or [project_path(args.parts_dir) / f"{name}.stl" for name in DEFAULT_PARTS]
    raw = run(
        args.model,
        parts,
        cfg["fences"],
        args.loc1,
        args.loc2,
        args.repeats,
        args.cold_repeats,
        sys.stderr,
        args.interval,
    )
    summary = summarise(raw)
    write_csv(args.out, raw)
    write_csv(args.summary, summary)
    for r in summary[summary["part"] == ALL_PARTS].itertuples(index=False):
        per = f", {r.median_ms_per_config:.3f} ms a configuration" if r.configs > 1 else ""
        print(f"{r.stage:>14}: median {r.median_ms:8.1f} ms (min {r.min_ms:.1f}, max {r.max_ms:.1f}){per}")
    return 0
