"""``--model analytic``: the untrained analytic push PMF as a predictor of predict and recommend."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from feeder.errors import FeederError
from feeder.learn import predict as P
from feeder.learn import recommend as R
from feeder.learn.analytic import AnalyticModel, is_analytic

REPO = Path(__file__).resolve().parents[1]
PART = REPO / "parts" / "rect-a2.stl"


def test_predict_normalises_and_accumulates_by_hand():
    model = AnalyticModel(4)
    pmf, cdf = model.predict(None, np.zeros((1, 8)), analytic=[[1.0, 0.0, 3.0, 0.0]])
    np.testing.assert_allclose(pmf, [[0.25, 0.0, 0.75, 0.0]])
    np.testing.assert_allclose(cdf, [[0.25, 0.25, 1.0, 1.0]])


@pytest.mark.parametrize(
    "analytic",
    [None, [[1.0, 0.0, 0.0]], [[0.0, 0.0, 0.0, 0.0]], [[1.0, -0.5, 0.0, 0.5]], [[np.nan, 1.0, 0.0, 0.0]]],
)
def test_bad_analytic_pmfs_are_one_line_errors(analytic):
    with pytest.raises(FeederError):
        AnalyticModel(4).predict(None, np.zeros((1, 8)), analytic=analytic)


def test_only_the_name_analytic_selects_it():
    assert is_analytic("analytic") and is_analytic(Path("analytic"))
    assert not is_analytic(None) and not is_analytic("models/m3")
    with pytest.raises(FeederError):
        AnalyticModel(0)


def test_predict_answers_the_smoothed_analytic_pmf_of_the_part_frame(tmp_path):
    from feeder.config import load_study_config, study_root
    from feeder.labels.dataset import label_smooth_deg
    from feeder.mechanics.hull import push_geometry
    from feeder.mechanics.pmf import analytic_pmf
    from feeder.parts.geometry import load_profile

    out = tmp_path / "a.csv"
    argv = ["--model", "analytic", "--part", str(PART), "--loc1", "straight:30", "--loc2", "none", "--out", str(out)]
    assert P.main(argv) == 0
    got = pd.read_csv(out)
    study = load_study_config(root=study_root())
    bins = int(study["labels"]["bins"])
    outline, holes, _ = load_profile(PART, "auto")
    smooth = label_smooth_deg(bins, float(study["labels"]["sigma_bins"]))
    want = analytic_pmf(
        push_geometry(outline, holes), "straight:30", "none", study["scene"], smooth_deg=smooth, bins=bins
    )
    np.testing.assert_allclose(got.pmf.to_numpy(), want / want.sum(), rtol=0, atol=1e-12)
    np.testing.assert_allclose(got.cdf.to_numpy(), np.cumsum(want / want.sum()), rtol=0, atol=1e-9)


def test_analytic_needs_an_stl_and_writes_nothing_without_one(tmp_path):
    out = tmp_path / "a.csv"
    with pytest.raises(FeederError, match="--part PART.stl"):
        P.main(["--model", "analytic", "--features", str(tmp_path / "f.json"), "--loc1", "none", "--loc2", "none"])
    assert not out.exists()


def test_recommend_ranks_with_the_analytic_pmf(tmp_path, capsys):
    out = tmp_path / "rank.csv"
    configs = "none_straight30,straight45_none"
    argv = ["--model", "analytic", "--part", str(PART), "--target", "0", "--tolerance", "10", "--configs", configs]
    assert R.main([*argv, "--out", str(out)]) == 0
    ranked = pd.read_csv(out)
    assert set(ranked.config_id) == set(configs.split(","))
    assert ranked.probability.between(0, 1).all()
    assert ranked.probability.is_monotonic_decreasing


@pytest.mark.parametrize("settings", ['{"scene": {}}', '{"labels": {"bins": 360, "sigma_bins": 1.0}}'])
def test_partial_settings_are_a_one_line_error_before_any_work(tmp_path, settings):
    out = tmp_path / "a.csv"
    argv = ["--model", "analytic", "--part", str(PART), "--loc1", "straight:30", "--loc2", "none"]
    with pytest.raises(FeederError, match="--settings lacks the config section"):
        P.main([*argv, "--out", str(out), "--settings", settings])
    with pytest.raises(FeederError, match="--settings lacks the config section"):
        R.main(
            ["--model", "analytic", "--part", str(PART), "--target", "0", "--tolerance", "5", "--settings", settings]
        )
    assert not out.exists()


def test_analytic_answers_the_evaluation_baseline_moved_to_the_part_frame(tmp_path):
    """The dataset's pmf_analytic (the evaluation's baseline) is in the feature frame (yaw + frame_deg);
    moved back by frame_deg it is what --model analytic answers, on a part whose frame is turned
    (lshape-a: about 338 deg)."""
    from feeder.config import load_study_config, study_root
    from feeder.labels import metrics as L
    from feeder.labels.dataset import label_smooth_deg
    from feeder.mechanics.hull import push_geometry
    from feeder.mechanics.pmf import analytic_pmf
    from feeder.parts.features import features_of_file
    from feeder.parts.geometry import load_profile

    part = REPO / "parts" / "lshape-a.stl"
    frame = features_of_file(part)["frame_deg"]
    assert 1.0 < frame % 360.0 < 359.0  # a turned frame, or the test shows nothing
    out = tmp_path / "a.csv"
    assert (
        P.main(
            ["--model", "analytic", "--part", str(part), "--loc1", "straight:45", "--loc2", "none", "--out", str(out)]
        )
        == 0
    )
    got = pd.read_csv(out).pmf.to_numpy()
    study = load_study_config(root=study_root())
    bins, outline_holes = int(study["labels"]["bins"]), load_profile(part, "auto")[:2]
    smooth = label_smooth_deg(bins, float(study["labels"]["sigma_bins"]))
    geom = push_geometry(*outline_holes)
    baseline = analytic_pmf(geom, "straight:45", "none", study["scene"], frame_deg=frame, smooth_deg=smooth, bins=bins)
    back = L.shift_pmf(baseline[None, :], -frame)[0]
    assert (
        float(L.circular_w1(L.cdf(got[None, :])[0], L.cdf(back[None, :])[0])) < 0.5
    )  # degrees: bin interpolation only
    # and the frame matters: unshifted, the baseline is elsewhere
    assert float(L.circular_w1(L.cdf(got[None, :])[0], L.cdf(baseline[None, :])[0])) > 5.0


def test_recommend_does_not_rank_a_configuration_that_always_jams_first():
    """The analytic PMF is over the ok drops: ranked by P(window) alone, a configuration whose drops
    all jam could top the list. Ranked by P(window) x ok mass it cannot."""
    from feeder.mechanics.features import PUSH_FEATURE_NAMES

    model = AnalyticModel(4)
    push = np.zeros((2, len(PUSH_FEATURE_NAMES)))
    push[:, PUSH_FEATURE_NAMES.index("ok_mass")] = [0.0, 0.9]  # the first always jams
    pmf = np.array([[1.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.5, 0.0]])  # ... and alone puts all its mass at 0 deg
    ranked = R.rank(model, np.zeros(45), None, ["straight30_none", "straight60_none"], 0.0, 10.0, 1, push, pmf)
    assert list(ranked.config_id) == ["straight60_none", "straight30_none"]
    np.testing.assert_allclose(ranked.predicted_ok_mass, [0.9, 0.0])
    np.testing.assert_allclose(ranked.probability_overall, ranked.probability * ranked.predicted_ok_mass)
    assert ranked.probability[1] > ranked.probability[0] > 0  # by P(window) alone the jamming one led


def test_predict_prints_the_analytic_ok_mass(tmp_path, capsys):
    argv = ["--model", "analytic", "--part", str(PART), "--loc1", "straight:30", "--loc2", "none"]
    assert P.main([*argv, "--out", str(tmp_path / "a.csv")]) == 0
    line = [x for x in capsys.readouterr().out.splitlines() if "without jamming" in x]
    assert len(line) == 1 and 0.0 <= float(line[0].rsplit(":", 1)[1]) <= 1.0
