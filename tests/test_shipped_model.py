"""The model the repository ships (models/m3, written by the default run's export_model job): a
fresh clone answers `feeder predict` and `feeder recommend` on a part of its own, with no --model."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from feeder.labels.dataset import features_version
from feeder.learn import predict as P
from feeder.learn import recommend as R
from feeder.learn.export import MODEL_DIR_ENV
from feeder.learn.models import TrainedModel

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "models" / "m3"
# an irregular hexagon (mm), in no library family: a user's own part
HEXAGON_MM = [(0.0, 0.0), (31.0, -4.0), (47.0, 9.0), (38.0, 26.0), (12.0, 30.0), (-6.0, 14.0)]
THICKNESS_MM = 7.0


@pytest.fixture(scope="module")
def own_part(tmp_path_factory) -> Path:
    from feeder.parts.geometry import stl_bytes

    path = tmp_path_factory.mktemp("own") / "my-bracket.stl"
    path.write_bytes(stl_bytes(np.array(HEXAGON_MM), THICKNESS_MM, "my-bracket"))
    assert not (ROOT / "parts" / path.name).exists()
    return path


def run_cli(*args: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != MODEL_DIR_ENV}  # the repository's own folder
    return subprocess.run([sys.executable, "-m", "feeder", *args], capture_output=True, text=True, env=env, timeout=300)


def test_the_repository_ships_model_3_with_its_card():
    card = json.loads((SHIPPED / "card.json").read_text())
    assert card["model"] == "m3" and card["features_version"] == features_version()
    for name, digest in card["files"].items():  # the card describes exactly these weights
        assert hashlib.sha256((SHIPPED / name).read_bytes()).hexdigest() == digest, name
    for split in ("test", "fences", "parts"):
        rows = {row["model"]: row for row in card["metrics"][split]}
        assert {"m3", "baseline_mean_pmf", "baseline_nearest_part"} <= set(rows)
        assert 0.0 < rows["m3"]["r2_mean"] <= 1.0
    assert (SHIPPED / "MODEL_CARD.md").read_text().strip()


def test_predict_answers_a_users_part_with_the_shipped_model_3(own_part, tmp_path):
    out = tmp_path / "pred.csv"
    m3 = ["--model", str(SHIPPED)]
    argv = ["predict", *m3, "--part", str(own_part), "--loc1", "straight:30", "--loc2", "none"]
    proc = run_cli(*argv, "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    got = pd.read_csv(out)
    assert list(got.columns) == ["angle_deg", "pmf", "cdf"] and len(got) == 360
    part_raw, frame_deg = P.part_vector(own_part, None)
    want = P.predict_frame(P.load_model(SHIPPED), part_raw, "straight:30", "none", frame_deg)
    np.testing.assert_allclose(got.pmf, want.pmf, atol=1e-12)
    torch_net = P.predict_frame(TrainedModel.load(SHIPPED), part_raw, "straight:30", "none", frame_deg)
    np.testing.assert_allclose(got.pmf, torch_net.pmf, rtol=1e-4)  # torch's float32 pass
    np.testing.assert_allclose(got.cdf, np.cumsum(got.pmf), atol=1e-9)
    assert got.pmf.min() >= 0.0 and got.cdf.iloc[-1] == pytest.approx(1.0)
    printed = run_cli("predict", *m3, "--part", str(own_part), "--loc1", "straight:30", "--loc2", "none")
    assert printed.returncode == 0 and "most likely final yaws" in printed.stderr  # the resting orientations


def test_recommend_ranks_fences_for_a_users_part_with_the_shipped_model_3(own_part, tmp_path):
    out = tmp_path / "rank.csv"
    ids = "straight30_none,curved45_straight20,none_curved10"
    argv = ["--target", "90", "--tolerance", "15", "--configs", ids, "--out", str(out)]
    proc = run_cli("recommend", "--model", str(SHIPPED), "--part", str(own_part), *argv)
    assert proc.returncode == 0, proc.stderr
    ranked = pd.read_csv(out)
    assert sorted(ranked.config_id) == sorted(ids.split(",")) and ranked.probability.is_monotonic_decreasing
    model = TrainedModel.load(SHIPPED)
    part_raw, frame_deg = P.part_vector(own_part, None)
    for row in ranked.itertuples():
        frame = P.predict_frame(model, part_raw, row.loc1, row.loc2, frame_deg)
        assert row.probability == pytest.approx(
            R.window_probability(frame.pmf.to_numpy(), 90.0, 15.0, order=1), abs=1e-7
        )
