"""feeder.bench.jams: the fence-angle jam survey (pure summary and a tiny CLI run)."""

import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
import yaml

from feeder.bench import jams

ROOT = Path(__file__).resolve().parents[1]
CFG = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())


def test_survey_jobs_cover_every_angle_at_both_locations():
    angles = {"straight_angles": [15, 45], "curved_angles": [0]}
    jobs = jams.survey_jobs(angles, ["a", "b"])
    assert len(jobs) == 3 * 2 * 2
    assert ("straight:15", "none", "a") in jobs and ("none", "curved:0", "b") in jobs
    assert all((l1 == "none") != (l2 == "none") for l1, l2, _ in jobs)  # exactly one fence


def test_summarize_means_over_parts():
    zero = {"ok": 0.0, "jammed": 0.0, "fell_off": 0.0, "timed_out": 0.0, "flipped": 0.0, "nan": 0.0}
    rows = [
        ("curved:60", "none", "a", dict(zero, ok=0.25, jammed=0.75)),
        ("curved:60", "none", "b", dict(zero, ok=0.75, jammed=0.25)),
        ("none", "curved:60", "a", dict(zero, ok=1.0)),
    ]
    df = jams.summarize(rows)
    mean = df[df["part"] == "mean"].set_index("location")
    assert mean.loc["loc1", "ok_rate"] == pytest.approx(0.5)
    assert mean.loc["loc1", "jammed_rate"] == pytest.approx(0.5)
    assert mean.loc["loc2", "ok_rate"] == pytest.approx(1.0)
    assert set(df["fence"]) == {"curved"} and set(df["angle_deg"]) == {60.0}


@pytest.mark.slow
def test_cli_tiny_survey(tmp_path):
    cfg = {k: CFG[k] for k in ("scene", "sim", "parts")}
    cfg["sim"] = dict(
        CFG["sim"],
        jam_survey={
            "parts": ["rect-a2"],
            "drops": 2,
            "preset": "coarse",
            "workers": 1,
            "straight_angles": [45],
            "curved_angles": [90],
        },
    )
    out = tmp_path / "jams.csv"
    r = subprocess.run(
        [sys.executable, "-m", "feeder", "bench-jams", "--settings", json.dumps(cfg), "--out-csv", str(out)],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    df = pd.read_csv(out)
    assert len(df) == 4 + 4  # 2 fences x 2 locations x 1 part, plus the mean rows
    assert df["ok_rate"].between(0, 1).all()


def test_cli_bad_settings_one_line_error(tmp_path):
    r = subprocess.run(
        [sys.executable, "-m", "feeder", "bench-jams", "--settings", "{", "--out-csv", str(tmp_path / "x.csv")],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert r.returncode != 0 and "not valid JSON" in r.stderr
    assert not (tmp_path / "x.csv").exists()
