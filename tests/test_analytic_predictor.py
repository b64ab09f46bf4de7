"""``--model analytic``: the untrained analytic push PMF as a predictor of predict and recommend."""

from __future__ import annotations

import json
import math
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
    (tmp_path / "f.json").write_text("{}")  # a features file, present: it still has no outline
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


def test_a_uniform_answer_names_no_preferred_yaw(tmp_path, capsys):
    """No fence: the analytic answer is uniform up to rounding; the summary, the plot and recommend's
    mode must not climb that rounding noise to a made-up peak."""
    from feeder.labels.metrics import is_uniform

    out, png = tmp_path / "u.csv", tmp_path / "u.png"
    argv = ["--model", "analytic", "--part", str(PART), "--loc1", "none", "--loc2", "none"]
    assert P.main([*argv, "--out", str(out), "--plot", str(png)]) == 0
    assert is_uniform(pd.read_csv(out).pmf.to_numpy())
    said = capsys.readouterr().out
    assert "no preferred final yaw" in said and "most likely" not in said
    assert png.stat().st_size > 0
    ranked = tmp_path / "r.csv"
    rargv = ["--model", "analytic", "--part", str(PART), "--target", "0", "--tolerance", "10"]
    assert R.main([*rargv, "--configs", "none_none,straight45_none", "--out", str(ranked)]) == 0
    modes = pd.read_csv(ranked).set_index("config_id").mode_deg
    assert np.isnan(modes["none_none"]) and np.isfinite(modes["straight45_none"])


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--symmetry", "7"], "--symmetry 7: part has no 7-fold symmetry"),
        (["--tolerance", "90"], "covers every yaw"),  # rect-a2 is 2-fold: windows of 180 deg each
        (["--symmetry", "1", "--tolerance", "180"], "give less than 180 deg"),
    ],
)
def test_recommend_refuses_a_symmetry_the_part_lacks_and_a_window_of_everything(tmp_path, capsys, extra, message):
    from feeder.cli import main as cli

    out = tmp_path / "r.csv"
    argv = ["recommend", "--model", "analytic", "--part", str(PART), "--target", "0", "--configs", "straight45_none"]
    if "--tolerance" not in extra:
        argv += ["--tolerance", "10"]
    assert cli([*argv, *extra, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()  # after the line that names the predictor
    assert message in err[-1] and err[-1].startswith("feeder recommend: error:") and not out.exists()


def test_recommend_takes_a_symmetry_the_part_has(tmp_path):
    out = tmp_path / "r.csv"
    argv = ["--model", "analytic", "--part", str(PART), "--target", "0", "--tolerance", "10"]
    for order in ("1", "2"):
        assert R.main([*argv, "--configs", "straight45_none", "--symmetry", order, "--out", str(out)]) == 0


@pytest.mark.parametrize(
    "part, message",
    [
        (None, "give exactly one of --part or --features"),
        ("folder", "is a folder, not a file"),
        ("p.obj", "unknown file type '.obj' (expected .stl or .xyz)"),
        ("gone.stl", "not found"),
    ],
)
@pytest.mark.parametrize("command", ["predict", "predict --simulate 4", "recommend"])
def test_a_part_argument_no_answer_can_read_is_one_line_before_any_work(tmp_path, capsys, part, message, command):
    """Also without --model (the study's answer), where the message used to be about features JSONs."""
    from feeder.cli import main as cli

    (tmp_path / "folder").mkdir()
    (tmp_path / "p.obj").write_text("v 0 0 0\n")
    out = tmp_path / "a.csv"
    argv = command.split()
    argv += (
        ["--loc1", "straight:30", "--loc2", "none"] if argv[0] == "predict" else ["--target", "0", "--tolerance", "5"]
    )
    if part is not None:
        argv += ["--part", str(tmp_path / part)]
    assert cli([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert message in err[-1] and not out.exists()


class _StudyLike:
    """rank's view of the study's predictor: a PMF per configuration, where each answer comes from
    and the analytic PMF's error by kind of scene (NaN for the other answers)."""

    label_frame = "part"

    def __init__(self, pmf, sources, errors):
        self.pmf, self._sources, self._errors = np.asarray(pmf, float), sources, np.asarray(errors, float)

    def predict(self, part_raw, feeder_raw, push_raw=None, analytic=None):
        return self.pmf, np.cumsum(self.pmf, axis=1)

    def sources(self):
        return self._sources

    def analytic_error_deg(self):
        return self._errors


def test_recommend_breaks_ties_by_how_often_the_analytic_pmf_is_right_there_and_says_so():
    sharp = np.zeros(360)
    sharp[0] = 1.0
    ids = ["straight30_none", "curved0_straight30", "none_straight30", "straight70_none"]
    model = _StudyLike(
        [sharp, sharp, sharp, np.full(360, 1 / 360)],
        ["analytic", "analytic", "structured", "analytic"],
        [9.1, 20.8, np.nan, 31.3],
    )
    ranked = R.rank(model, np.zeros(45), None, ids, 0.0, 5.0, 1)
    # equal probabilities (1.0): the structured answer, then the kind the analytic PMF gets right more often
    assert ranked.config_id.tolist() == ["none_straight30", "straight30_none", "curved0_straight30", "straight70_none"]
    assert ranked.probability.tolist()[:3] == [1.0, 1.0, 1.0]
    note = R.analytic_note(ranked.head(3))
    assert note.startswith("note: 2 of these answers are the analytic push PMF, which lay 9-21 deg")
    assert R.analytic_note(ranked.iloc[[0]]) == ""  # no analytic answer shown: nothing to say
    assert R.analytic_note(ranked.drop(columns="analytic_w1_deg")) == ""


def test_recommend_shows_how_far_a_structured_answer_may_be_off():
    sharp = np.zeros(360)
    sharp[0] = 1.0
    model = _StudyLike([sharp, sharp, sharp], ["structured", "structured", "simulated"], [np.nan] * 3)
    model.structured_error_deg = lambda: np.array([2.8, 12.9, np.nan])
    ranked = R.rank(model, np.zeros(45), None, ["straight30_none", "straight75_none", "straight40_none"], 0.0, 5.0, 1)
    assert ranked.structured_w1_deg.tolist()[:2] == [2.8, 12.9] and np.isnan(ranked.structured_w1_deg.iloc[2])
    note = R.structured_note(ranked)
    assert note.startswith("note: 2 of these answers are the structured predictor, which lay 3-13 deg")
    assert R.structured_note(ranked.iloc[[0]]).startswith(
        "note: 1 of these answers are the structured predictor, which lay 3 deg"
    )
    assert R.structured_note(ranked.iloc[[2]]) == "" and R.structured_note(ranked.drop(columns="answer")) == ""


def test_recommend_shows_how_far_a_simulated_label_may_be_off():
    """The study's own labels carry their audit's upper estimate as a column and a note (the
    largest shown, how many have none, that these are bounds); labels without an audit say that they
    have none; a table without labels says nothing."""
    sharp = np.zeros(360)
    sharp[0] = 1.0
    ids = ["straight30_none", "straight75_none", "straight40_none", "straight50_none"]
    model = _StudyLike([sharp] * 4, ["simulated", "simulated", "analytic", "simulated"], [np.nan, np.nan, 9.1, np.nan])
    model.label_error_deg = lambda: np.array([0.8, 2.4, np.nan, np.nan])
    ranked = R.rank(model, np.zeros(45), None, ids, 0.0, 5.0, 1)
    by_id = ranked.set_index("config_id").label_w1_upper_deg
    assert by_id["straight30_none"] == 0.8 and by_id["straight75_none"] == 2.4
    assert np.isnan(by_id["straight40_none"]) and np.isnan(by_id["straight50_none"])
    note = R.label_note(ranked)
    assert note.startswith("note: 3 of these answers are the study's simulated labels; their audits bound")
    assert "at most 2.4 deg here (1 without one) (upper bounds" in note and "not comparable" in note
    first = ranked[ranked.config_id == "straight30_none"]
    assert R.label_note(first).startswith(
        "note: 1 of these answers is the study's simulated label; their audits bound each one's circular W1 from "
        "the simulator's exact label, at most 0.8 deg here (upper bounds"
    )
    assert R.label_note(ranked[ranked.config_id == "straight50_none"]) == (
        "note: 1 of these answers is the study's simulated label, without an audit estimate of their error; "
        "--verify K simulates the top K"
    )
    assert R.label_note(ranked[ranked.answer == "analytic"]) == ""
    assert R.label_note(ranked.drop(columns="label_w1_upper_deg")) == ""
    model = _StudyLike([sharp] * 2, ["analytic", "analytic"], [9.1, 9.1])
    model.label_error_deg = lambda: np.array([np.nan, np.nan])
    assert "label_w1_upper_deg" not in R.rank(model, np.zeros(45), None, ids[:2], 0.0, 5.0, 1)  # no label answered


def test_recommend_prints_only_the_error_columns_of_the_answers_it_shows(tmp_path, capsys):
    """The study's predictor for a library part: the CSV keeps every error column; the printed
    table leaves out those blank in every row it shows, and each note goes with its answers."""
    part = REPO / "parts" / "lshape-a.stl"
    configs = "none_curved30,none_curved80"  # a structured answer, and the study's audited label
    out = tmp_path / "r.csv"
    base = ["--part", str(part), "--target", "0", "--tolerance", "10", "--configs", configs, "--out", str(out)]
    assert R.main([*base, "--top", "2"]) == 0
    ranked = pd.read_csv(out)
    assert set(ranked.answer) == {"structured", "simulated"}
    assert {"structured_w1_deg", "label_w1_upper_deg", "analytic_w1_deg"} <= set(ranked.columns)
    header = capsys.readouterr().out.splitlines()
    table = next(line for line in header if line.lstrip().startswith("config_id"))
    # the structured answer's error column is printed where the card carries its error bins
    # (structured_by_distance.csv of `feeder structured`; absent while the protocol is not rerun on the
    # study's labels: then that column is blank in every row and left out like the analytic one)
    binned = bool(json.loads((REPO / "models" / "study" / "card.json").read_text())["structured"]["by_distance"])
    assert ("structured_w1_deg" in table) is binned
    assert "label_w1_upper_deg" in table and "analytic_w1_deg" not in table
    assert any(line.startswith("note: 1 of these answers is the study's simulated label;") for line in header)
    assert R.main([*base, "--top", "1"]) == 0
    said = capsys.readouterr().out.splitlines()
    table = next(line for line in said if line.lstrip().startswith("config_id"))
    first = pd.read_csv(out).answer.iloc[0]
    mine, other = ("structured_w1_deg", "label_w1_upper_deg")[:: 1 if first == "structured" else -1]
    assert (mine in table) is (binned or first != "structured") and other not in table
    assert any("simulated label" in line for line in said) == (first == "simulated")


def test_tipping_ratio_by_hand():
    from feeder.config import load_study_config, study_root
    from feeder.learn.predict import tipping_ratio

    scene = load_study_config(root=study_root())["scene"]
    scene = {
        **scene,
        "part": {**scene["part"], "friction": 0.8},
        "belt": {**scene["belt"], "friction": 1.0},
        "fences": {**scene["fences"], "clearance": 0.0005, "height": 0.03},
    }
    plate = np.array([[0, 0], [0.04, 0], [0.04, 0.02], [0, 0.02]], float)
    # pushed across its 20 mm: far side 10 mm from the centroid; contact centre (0.5 + 5) / 2 mm
    assert tipping_ratio(plate, [0.02, 0.01], 0.005, scene) == pytest.approx(0.8 * 2.75 / 10.0)
    # a 1 x 1 mm rod: the fence meets it above its 0.5 mm gap only, at 0.75 mm; far side 0.5 mm
    rod = np.array([[0, 0], [0.1, 0], [0.1, 0.001], [0, 0.001]], float)
    assert tipping_ratio(rod, [0.05, 0.0005], 0.001, scene) == pytest.approx(0.8 * 0.75 / 0.5)
    # taller than the fence: the contact's centre is the fence face's, (0.5 + 30.5) / 2 mm
    assert tipping_ratio(plate, [0.02, 0.01], 0.05, scene) == pytest.approx(0.8 * 15.5 / 10.0)
    # a right triangle (0,0), (30,0), (0,30) mm, centroid (10, 10): pushed on a leg it would tip over
    # the opposite corner, 20 mm away; on the hypotenuse over the right angle, 20/sqrt(2) mm: the least
    tri = np.array([[0, 0], [0.03, 0], [0, 0.03]], float)
    assert tipping_ratio(tri, [0.01, 0.01], 0.005, scene) == pytest.approx(0.8 * 2.75 / (20.0 / math.sqrt(2.0)))


def test_a_part_too_tall_for_its_width_gets_a_note_that_a_fence_may_tip_it(tmp_path, capsys):
    from feeder.parts.geometry import stl_bytes

    needle = tmp_path / "needle.stl"
    needle.write_bytes(stl_bytes(np.array([[0, 0], [0.1, 0], [0.1, 0.001], [0, 0.001]], float), 0.005))
    argv = ["--model", "analytic", "--loc1", "straight:30", "--loc2", "none", "--out", str(tmp_path / "a.csv")]
    assert P.main([*argv, "--part", str(needle)]) == 0
    assert "would tip it over (4.40 of the tipping moment" in capsys.readouterr().err
    assert P.main([*argv, "--part", str(PART)]) == 0
    assert "tip it over" not in capsys.readouterr().err  # a study part: well below


def test_orientation_summary_of_a_peaked_answer_still_names_its_modes():
    pmf = np.full(360, 0.2 / 358)
    pmf[[10, 190]] = 0.4
    frame = pd.DataFrame({"angle_deg": np.arange(360.0), "pmf": pmf})
    assert P.orientation_summary(frame).startswith("most likely final yaws (part frame): ")


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
