"""`feeder predict` on a tiny trained model."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from factories import make_regression_dataset, small_overrides

from feeder.config import compose_config
from feeder.errors import FeederError
from feeder.labels.dataset import load_dataset
from feeder.learn import predict as P
from feeder.learn import train as T

PARTS = Path(__file__).resolve().parents[1] / "parts"


@pytest.fixture(scope="module")
def model_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("pred")
    make_regression_dataset(root / "ds.npz")
    T.train(compose_config("train", small_overrides(root / "ds.npz", root / "m3", "m3", epochs=2)))
    data = load_dataset(root / "ds.npz")
    raw = data["part_raw"][0].reshape(15, 3)
    (root / "p0.json").write_text(
        json.dumps({"k": raw[:, 0].tolist(), "magnitude": raw[:, 1].tolist(), "phase": raw[:, 2].tolist()})
    )
    return root


def test_predict_csv_matches_model(model_dir, tmp_path):
    from feeder.labels.dataset import feeder_vector
    from feeder.lane.fences import parse_location
    from feeder.learn.models import TrainedModel

    out = tmp_path / "pmf.csv"
    args = [
        "--model",
        str(model_dir / "m3"),
        "--features",
        str(model_dir / "p0.json"),
        "--loc1",
        "straight:30",
        "--loc2",
        "none",
        "--out",
        str(out),
        "--plot",
        str(tmp_path / "p.png"),
    ]
    assert P.main(args) == 0
    df = pd.read_csv(out)
    assert list(df.columns) == ["angle_deg", "pmf", "cdf"] and len(df) == 360
    assert df.angle_deg.iloc[1] == 1.0 and df.pmf.sum() == pytest.approx(1.0)
    assert np.allclose(np.cumsum(df.pmf), df.cdf)
    data = load_dataset(model_dir / "ds.npz")
    fv = feeder_vector(parse_location("straight:30"), parse_location("none"))
    pmf, _ = TrainedModel.load(model_dir / "m3").predict(data["part_raw"][:1], fv[None])
    assert np.allclose(df.pmf, pmf[0])
    assert (tmp_path / "p.png").read_bytes()[:4] == b"\x89PNG"


def test_predict_prints_the_most_likely_orientations_of_its_pmf(model_dir, tmp_path, capsys):
    from feeder.labels.metrics import resting_orientations

    out = tmp_path / "pmf.csv"
    base = ["--model", str(model_dir / "m3"), "--features", str(model_dir / "p0.json")]
    assert P.main([*base, "--loc1", "straight:30", "--loc2", "none", "--out", str(out)]) == 0
    printed = capsys.readouterr().out.strip()
    modes = resting_orientations(pd.read_csv(out).pmf.to_numpy(), P.TOP_ORIENTATIONS)
    assert printed == "most likely final yaws (part frame): " + ", ".join(
        f"{yaw:.1f} deg p={mass:.2f}" for yaw, mass in modes
    )


def test_predict_to_stdout(model_dir, capsys):
    """The printed table holds the model's own forward pass for that part and fence pair."""
    import io

    from feeder.labels.dataset import feeder_vector
    from feeder.lane.fences import parse_location
    from feeder.learn.models import TrainedModel

    code = P.main(
        [
            "--model",
            str(model_dir / "m3"),
            "--features",
            str(model_dir / "p0.json"),
            "--loc1",
            "curved:45",
            "--loc2",
            "straight:20",
        ]
    )
    out = capsys.readouterr()
    assert code == 0 and out.out.startswith("angle_deg,pmf,cdf") and "ms" in out.err
    df = pd.read_csv(io.StringIO(out.out))
    data = load_dataset(model_dir / "ds.npz")
    fv = feeder_vector(parse_location("curved:45"), parse_location("straight:20"))
    pmf, _ = TrainedModel.load(model_dir / "m3").predict(data["part_raw"][:1], fv[None])
    assert len(df) == 360 and np.allclose(df.pmf, pmf[0], atol=1e-6)
    assert np.allclose(df.cdf, np.cumsum(pmf[0]), atol=1e-5)


def test_predict_out_dash_is_stdout_not_a_file_named_dash(model_dir, tmp_path, monkeypatch, capsys):
    """``--out -`` means stdout: the CSV is printed (the summary goes to stderr) and no file is made."""
    import io

    monkeypatch.chdir(tmp_path)
    base = ["--model", str(model_dir / "m3"), "--features", str(model_dir / "p0.json")]
    assert P.main([*base, "--loc1", "straight:30", "--loc2", "none", "--out", "-"]) == 0
    out = capsys.readouterr()
    assert not (tmp_path / "-").exists()
    assert len(pd.read_csv(io.StringIO(out.out))) == 360 and "most likely final yaws" in out.err


def test_recommend_out_dash_prints_the_csv_and_moves_the_table_to_stderr(model_dir, tmp_path, monkeypatch, capsys):
    import io

    from feeder.learn import recommend as R

    monkeypatch.chdir(tmp_path)
    ids = ["straight30_none", "curved45_straight20", "none_curved10"]
    base = ["--model", str(model_dir / "m3"), "--features", str(model_dir / "p0.json")]
    argv = [*base, "--target", "90", "--tolerance", "15", "--configs", ",".join(ids), "--out", "-"]
    assert R.main(argv) == 0
    out = capsys.readouterr()
    assert not (tmp_path / "-").exists()
    ranked = pd.read_csv(io.StringIO(out.out))
    assert sorted(ranked.config_id) == sorted(ids) and "within 15 deg of 90 deg" in out.err


@pytest.mark.parametrize("loc1", ["straight:95", "wedge:3", "straight"])
def test_bad_fences_write_nothing(model_dir, tmp_path, loc1):
    out = tmp_path / "x.csv"
    with pytest.raises(FeederError):
        P.main(
            [
                "--model",
                str(model_dir / "m3"),
                "--features",
                str(model_dir / "p0.json"),
                "--loc1",
                loc1,
                "--loc2",
                "none",
                "--out",
                str(out),
            ]
        )
    assert not out.exists()


def test_missing_model_or_part(model_dir, tmp_path):
    with pytest.raises(FeederError):
        P.main(["--model", str(tmp_path), "--features", str(model_dir / "p0.json"), "--loc1", "none", "--loc2", "none"])
    with pytest.raises(FeederError):
        P.main(
            ["--model", str(model_dir / "m3"), "--part", str(tmp_path / "nope.stl"), "--loc1", "none", "--loc2", "none"]
        )


@pytest.mark.skipif(not any(PARTS.glob("*.stl")), reason="no part library in parts/")
def test_predict_from_stl(model_dir, tmp_path):
    stl = sorted(PARTS.glob("*.stl"))[0]
    out = tmp_path / "stl.csv"
    assert (
        P.main(
            [
                "--model",
                str(model_dir / "m3"),
                "--part",
                str(stl),
                "--loc1",
                "straight:30",
                "--loc2",
                "none",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert pd.read_csv(out).pmf.sum() == pytest.approx(1.0)


def test_plot_draws_the_part_at_its_most_likely_yaw(tmp_path):
    from feeder.labels.metrics import resting_orientations

    square = np.array([[0.0, 0.0], [0.02, 0.0], [0.02, 0.01], [0.0, 0.01]])
    pmf = np.zeros(360)
    pmf[[30, 200]] = [0.7, 0.3]
    frame = pd.DataFrame({"angle_deg": np.arange(360.0), "pmf": pmf, "cdf": np.cumsum(pmf)})
    fig = P.plot(frame, "t", square)
    part_ax = fig.axes[1]
    yaw, _ = resting_orientations(pmf, 1)[0]
    assert yaw == pytest.approx(30.5) and "30.5 deg" in part_ax.get_title()
    drawn = np.column_stack(part_ax.get_lines()[0].get_data())[:-1]
    np.testing.assert_allclose(drawn, P.rotated_outline(square, 30.5))
    np.testing.assert_allclose(P.rotated_outline(square, 90.0)[0], [5.0, -10.0], atol=1e-9)  # by hand
    assert len(P.plot(frame, "t").axes) == 2  # without a part: the PMF and its CDF axis only
    # a hole turns with its part, about the part's centre (0.01, 0.005): its corner (0.012, 0.002)
    # lies at (2, -3) mm from it, so at 90 deg it is drawn at (3, 2)
    hole = np.array([[0.012, 0.002], [0.014, 0.002], [0.014, 0.004]])
    pmf90 = np.zeros(360)
    pmf90[90] = 1.0
    frame90 = pd.DataFrame({"angle_deg": np.arange(360.0), "pmf": pmf90, "cdf": np.cumsum(pmf90)})
    lines = P.plot(frame90, "t", square, [hole]).axes[1].get_lines()
    drawn_hole = np.column_stack(lines[1].get_data())[:-1]
    np.testing.assert_allclose(drawn_hole, P.rotated_outline(hole, 90.5, centre=square.mean(axis=0)))
    np.testing.assert_allclose(P.rotated_outline(hole, 90.0, centre=square.mean(axis=0))[0], [3.0, 2.0], atol=1e-9)


def test_principal_frame_model_answers_in_the_part_frame(model_dir, tmp_path):
    """A model trained on feature-frame labels: its PMF is moved back by the part's frame_deg."""
    from feeder.labels import metrics as L
    from feeder.learn.models import TrainedModel

    m = TrainedModel.load(model_dir / "m3")
    assert m.label_frame == "part"  # make_regression_dataset carries no label_frame: the part frame
    m.label_frame = "principal"
    m.save(tmp_path / "mp")
    assert TrainedModel.load(tmp_path / "mp").label_frame == "principal"
    feats = json.loads((model_dir / "p0.json").read_text())
    (tmp_path / "p0f.json").write_text(json.dumps({**feats, "frame_deg": 30.0}))
    base = ["--model", str(tmp_path / "mp"), "--loc1", "straight:30", "--loc2", "none"]
    assert P.main(base + ["--features", str(tmp_path / "p0f.json"), "--out", str(tmp_path / "a.csv")]) == 0
    assert (
        P.main(
            [
                "--model",
                str(model_dir / "m3"),
                "--loc1",
                "straight:30",
                "--loc2",
                "none",
                "--features",
                str(model_dir / "p0.json"),
                "--out",
                str(tmp_path / "b.csv"),
            ]
        )
        == 0
    )
    got, same_net = pd.read_csv(tmp_path / "a.csv"), pd.read_csv(tmp_path / "b.csv")
    np.testing.assert_allclose(got.pmf, L.shift_pmf(same_net.pmf.to_numpy(), -30.0), atol=1e-12)
    np.testing.assert_allclose(got.cdf, np.cumsum(got.pmf), atol=1e-12)
    with pytest.raises(FeederError, match="frame_deg"):  # features without the frame
        P.main(base + ["--features", str(model_dir / "p0.json")])


# ---------------------------------------------------------------- feeder recommend
def test_window_probability_by_hand_with_wrap_around_and_symmetry():
    from feeder.learn.recommend import window_probability

    pmf = np.zeros(360)
    pmf[[0, 5, 90, 180, 355]] = [0.1, 0.2, 0.3, 0.25, 0.15]  # bins [k, k + 1)
    assert window_probability(pmf, 0.0, 10.0) == pytest.approx(0.1 + 0.2 + 0.15)  # straddles 0/360
    assert window_probability(pmf, 0.0, 10.0, order=2) == pytest.approx(0.45 + 0.25)  # and 180 +- 10
    assert window_probability(pmf, 90.5, 0.25) == pytest.approx(0.3 * 0.5)  # half of bin 90
    assert window_probability(pmf, 45.0, 100.0, order=4) == pytest.approx(1.0)  # windows cover the circle
    for bad in [
        dict(target_deg=360.0, tolerance_deg=5),
        dict(target_deg=0.0, tolerance_deg=0),
        dict(target_deg=0.0, tolerance_deg=5, order=0),
    ]:
        with pytest.raises(FeederError):
            window_probability(pmf, **bad)


def test_recommend_ranks_configurations_by_the_models_own_predictions(model_dir, tmp_path, capsys):
    from feeder.learn import recommend as R

    ids = ["straight30_none", "curved45_straight20", "none_curved10"]
    out = tmp_path / "rank.csv"
    base = ["--model", str(model_dir / "m3"), "--features", str(model_dir / "p0.json")]
    argv = [*base, "--target", "90", "--tolerance", "15", "--symmetry", "2", "--configs", ",".join(ids)]
    assert R.main([*argv, "--out", str(out), "--top", "2"]) == 0
    ranked = pd.read_csv(out)
    assert sorted(ranked.config_id) == sorted(ids) and ranked.probability.is_monotonic_decreasing
    model = P.load_model(model_dir / "m3")  # what recommend answers with: the network in numpy
    data = load_dataset(model_dir / "ds.npz")
    for _, row in ranked.iterrows():
        frame = P.predict_frame(model, data["part_raw"][0], row.loc1, row.loc2)
        want = R.window_probability(frame.pmf.to_numpy(), 90.0, 15.0, order=2)
        assert row.probability == pytest.approx(want, abs=1e-9)
    printed = capsys.readouterr().out
    assert "within 15 deg of 90 deg, 2-fold symmetric" in printed and ranked.config_id[0] in printed


@pytest.mark.parametrize(
    "args, message",
    [
        (["--target", "400", "--tolerance", "5"], "target must be in"),
        (["--target", "0", "--tolerance", "-1"], "tolerance"),
        (["--target", "0", "--tolerance", "180"], "covers every yaw"),
    ],
)
def test_recommend_bad_input_is_one_line_and_writes_nothing(model_dir, tmp_path, capsys, args, message):
    from feeder.cli import main

    out = tmp_path / "rank.csv"
    argv = ["recommend", "--model", str(model_dir / "m3"), "--features", str(model_dir / "p0.json"), *args]
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err and not out.exists()


@pytest.mark.skipif(not (PARTS / "rect-a2.stl").is_file(), reason="no part library in parts/")
def test_recommend_verify_simulates_the_top_k_as_the_workflow_labels_them(model_dir, tmp_path, capsys):
    """--verify 1: the top configuration simulated with the study's adaptive settings; its
    simulated probability is the window probability of `feeder simulate` + `feeder labels pmf`
    run by hand; the others are not simulated."""
    from feeder.config import load_study_config
    from feeder.labels.pmf import sim_label
    from feeder.learn import recommend as R
    from feeder.sim import simulate as S
    from feeder.sim.record import load_sim

    part = PARTS / "rect-a2.stl"
    out = tmp_path / "rank.csv"
    argv = ["--model", str(model_dir / "m3"), "--part", str(part), "--target", "0", "--tolerance", "10"]
    argv += ["--configs", "straight30_none,curved40_none", "--verify", "1", "--out", str(out)]
    assert R.main(argv) == 0
    ranked = pd.read_csv(out)
    assert list(ranked.columns[-len(R.VERIFY_COLUMNS) :]) == list(R.VERIFY_COLUMNS)
    assert ranked.simulations.notna().tolist() == [True, False]
    top = ranked.iloc[0]
    loc1, loc2 = top.loc1, top.loc2
    study = load_study_config()
    sim, adaptive = study["sim"], study["sim"]["adaptive"]
    npz = tmp_path / "sim.npz"
    by_hand = ["--part", str(part), "--loc1", loc1, "--loc2", loc2, "--drops", str(sim["drops"])]
    by_hand += ["--seed", str(sim["base_seed"]), "--preset", sim["preset"], "--yaw-sampling", "adaptive"]
    by_hand += ["--n0", str(adaptive["n0"]), "--tolerance-deg", str(adaptive["tolerance_deg"])]
    by_hand += ["--min-width-deg", str(adaptive["min_width_deg"]), "--symmetry", str(adaptive["symmetry"])]
    assert S.main([*by_hand, "--out", str(npz)]) == 0
    label = sim_label(load_sim(npz), study["labels"]["bins"], study["labels"]["sigma_bins"])
    order = R.symmetry_order("auto", part)
    assert order == 2
    assert top.simulated_probability == pytest.approx(R.window_probability(label.pmf, 0.0, 10.0, order), abs=1e-12)
    assert top.ok_mass == pytest.approx(label.ok_mass, abs=1e-12) and top.simulations == label.simulations
    printed = capsys.readouterr()
    assert "predicted" in printed.out and "simulated" in printed.out and top.config_id in printed.out
    assert f"verify 1/1 {top.config_id}" in printed.err


def fake_simulation(jammed: set[str], drops: int = 8):
    """A stand-in for feeder.sim.simulate.simulate: every drop of a configuration in ``jammed``
    jams; the others' drops all end ok at 0 deg (random initial yaws: a drawn design)."""
    from feeder.lane.fences import config_id

    def simulate(geom, loc1, loc2, budget, seed, scene, preset, preset_name, **_):
        cid = config_id(loc1, loc2)
        status = np.array(["jammed" if cid in jammed else "ok"] * drops)
        return {
            "final_yaw_deg": np.zeros(drops),
            "initial_yaw_deg": np.linspace(0.0, 360.0, drops, endpoint=False),
            "status": status,
            "cpu_s": 0.5,
            "meta": json.dumps({"yaw_sampling": "random", "config_id": cid}),
        }

    return simulate


def test_verify_reports_a_jammed_configuration_and_keeps_the_others(monkeypatch):
    """A configuration whose drops all jam is an answer (ok mass 0, its statuses, no simulated
    probability), not an error; the next one is verified as usual; progress goes to the log."""
    from feeder.learn import recommend as R
    from feeder.sim import simulate as S

    monkeypatch.setattr(S, "simulate", fake_simulation({"curved40_none"}))
    settings = {"budget": 8, "seed": 0, "scene": {}, "preset": {}, "preset_name": "fast", "adaptive": {}}
    settings |= {"bins": 360, "sigma": 0.0}
    lines: list[str] = []
    got = R.verify(None, ["curved40_none", "straight30_none"], settings, 0.0, 10.0, 1, lines.append)
    assert list(got.columns) == ["config_id", *R.VERIFY_COLUMNS]
    jam, ok = got.iloc[0], got.iloc[1]
    assert jam.config_id == "curved40_none" and jam.ok_mass == 0.0 and np.isnan(jam.simulated_probability)
    assert jam.statuses == "jammed 8" and jam.simulations == 8
    assert ok.ok_mass == 1.0 and ok.simulated_probability == pytest.approx(1.0) and ok.statuses == "ok 8"
    assert sum("verify 1/2 curved40_none" in line for line in lines) == 2  # before and after
    assert "jammed 8" in lines[1] and "verify 2/2 straight30_none" in lines[2]


def test_status_counts_most_frequent_first():
    from feeder.learn.recommend import status_counts

    assert status_counts(["ok", "jammed", "fell_off", "jammed"]) == "jammed 2, fell_off 1, ok 1"
    assert status_counts(np.array(["jammed"] * 3)) == "jammed 3"


@pytest.mark.skipif(not (PARTS / "rect-a2.stl").is_file(), reason="no part library in parts/")
def test_recommend_verify_keeps_the_ranking_when_the_top_pick_jams(model_dir, tmp_path, monkeypatch, capsys):
    from feeder.cli import main
    from feeder.learn import recommend as R
    from feeder.sim import simulate as S

    ids = ["straight30_none", "curved45_straight20", "none_curved10"]
    base = ["--model", str(model_dir / "m3"), "--part", str(PARTS / "rect-a2.stl"), "--target", "0"]
    base += ["--tolerance", "10", "--configs", ",".join(ids)]
    assert R.main([*base, "--out", str(tmp_path / "plain.csv")]) == 0
    top = pd.read_csv(tmp_path / "plain.csv").config_id[0]
    monkeypatch.setattr(S, "simulate", fake_simulation({top}))
    out = tmp_path / "rank.csv"
    assert main(["recommend", *base, "--verify", "2", "--out", str(out)]) == 0
    ranked = pd.read_csv(out)
    assert len(ranked) == len(ids) and ranked.config_id[0] == top  # the whole ranking, in its order
    assert ranked.ok_mass[0] == 0.0 and ranked.statuses[0] == "jammed 8" and np.isnan(ranked.simulated_probability[0])
    assert ranked.ok_mass[1] == 1.0 and ranked.simulations.notna().tolist() == [True, True, False]
    printed = capsys.readouterr()
    assert top in printed.out and "jammed 8" in printed.out
    assert f"verify 1/2 {top}" in printed.err and "verify 2/2" in printed.err


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--features", "p0.json", "--verify", "1"], "--verify simulates the part"),
        (["--part", "missing.stl", "--verify", "1"], "not found"),
        (["--features", "p0.json", "--verify", "-1"], "--verify must be 0 or more"),
    ],
)
def test_recommend_verify_bad_input_is_one_line_before_any_work(model_dir, tmp_path, capsys, extra, message):
    from feeder.cli import main

    extra = [str(model_dir / e) if e.endswith((".json", ".stl")) else e for e in extra]
    out = tmp_path / "rank.csv"
    argv = ["recommend", "--model", str(model_dir / "m3"), "--target", "0", "--tolerance", "10", *extra]
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err and not out.exists()


def test_recommend_ranks_the_study_grid_by_default(model_dir, capsys):
    from feeder.config import load_study_config
    from feeder.learn import recommend as R

    fences = load_study_config()["fences"]
    grid = R.grid_configurations(fences)
    s, c = len(fences["straight_angles"]), len(fences["curved_angles"])
    assert len(grid) == len(set(grid)) == 2 * s + 2 * c + s * s + 2 * s * c + c * c  # the 8 combinations
    base = ["--model", str(model_dir / "m3"), "--features", str(model_dir / "p0.json")]
    assert R.main([*base, "--target", "0", "--tolerance", "10"]) == 0
    assert f"{len(grid)} configurations" in capsys.readouterr().out


def test_predict_answers_a_part_with_a_hole_with_a_note(model_dir, tmp_path, capsys):
    """A plate with a bolt hole: answered (the features are its outer contour, as in the paper), with
    one note on stderr that the model does not see the hole; the same plate without it gets none.
    The features of the STL are those of the face cloud `feeder parts xyz` exports from it (the
    hole left out of both, so the principal frame is the holed face's)."""
    from feeder.parts.geometry import stl_bytes
    from feeder.parts.shapes import holes_mm, outline_mm

    spec = "plate-60x30x10"
    for name, holes in (("holed", holes_mm(spec)), ("solid", [])):
        part = tmp_path / f"{name}.stl"
        part.write_bytes(stl_bytes(outline_mm(spec), 5.0, name, holes=holes))
        argv = ["--model", str(model_dir / "m3"), "--part", str(part), "--loc1", "straight:30", "--loc2", "none"]
        assert P.main([*argv, "--out", str(tmp_path / f"{name}.csv")]) == 0
        notes = [line for line in capsys.readouterr().err.splitlines() if "through-hole" in line]
        assert notes == (
            [
                "feeder predict: note: holed.stl has 1 through-hole(s); the model sees its outer "
                "contour only, so check the answer with feeder simulate"
            ]
            if holes
            else []
        )
    from feeder.cli import main as cli
    from feeder.parts.features import DFT, as_vector, features_of_file

    xyz = tmp_path / "holed.xyz"
    assert (
        cli(["parts", "xyz", str(tmp_path / "holed.stl"), "--out", str(xyz), "--points", str(DFT.stl_cloud_points)])
        == 0
    )
    of_stl, of_xyz = (as_vector(features_of_file(p)).reshape(-1, 3) for p in (tmp_path / "holed.stl", xyz))
    np.testing.assert_array_equal(of_stl[:, 0], of_xyz[:, 0])  # the same frequencies
    # the xyz export rounds to 1e-4 mm: magnitudes agree to 1e-5 of the largest
    np.testing.assert_allclose(of_stl[:, 1], of_xyz[:, 1], atol=1e-5 * of_stl[:, 1].max())
    np.testing.assert_allclose(of_stl[:, 2], of_xyz[:, 2], atol=1e-2)
    # the hole shifts the face's principal frame, so the two plates differ
    solid = as_vector(features_of_file(tmp_path / "solid.stl")).reshape(-1, 3)
    assert not np.allclose(of_stl, solid)


def test_the_hole_note_only_where_the_answer_cannot_see_the_hole(model_dir, tmp_path, capsys):
    """The analytic push PMF sees a part's holes (its centre of mass is the holed face's), so its
    answer for a holed plate differs from the solid plate's and carries no note; neither does the
    simulator's (``--simulate``). A trained network reads the outer contour's features: the note."""
    from feeder.learn.analytic import AnalyticModel
    from feeder.learn.predict import reads_contour_only
    from feeder.parts.geometry import stl_bytes
    from feeder.parts.shapes import holes_mm, outline_mm

    spec = "plate-60x30x10"
    pmfs = {}
    for name, holes in (("holed", holes_mm(spec)), ("solid", [])):
        part = tmp_path / f"{name}.stl"
        part.write_bytes(stl_bytes(outline_mm(spec), 5.0, name, holes=holes))
        out = tmp_path / f"{name}.csv"
        # straight:30: the hole's shift of the centre of mass moves a resting yaw of mass 0.35 by a degree
        # (at straight:40, under the round fence tip, its answer moves by only 0.004)
        argv = ["--model", "analytic", "--part", str(part), "--loc1", "straight:30", "--loc2", "none"]
        assert P.main([*argv, "--out", str(out)]) == 0
        assert "through-hole" not in capsys.readouterr().err
        pmfs[name] = pd.read_csv(out).pmf.to_numpy()
    assert np.abs(np.cumsum(pmfs["holed"]) - np.cumsum(pmfs["solid"])).max() > 0.01  # the hole moves the answer
    assert not reads_contour_only(AnalyticModel(360))
    assert reads_contour_only(P.load_model(model_dir / "m3"))  # the paper's inputs: the DFT alone
    shipped = PARTS.parent / "models" / "m3pushonly"
    if shipped.is_dir():  # fence+push inputs: the push block of the holed face, no DFT
        assert not reads_contour_only(P.load_model(shipped))
    holed = ["--part", str(tmp_path / "holed.stl"), "--loc1", "straight:40", "--loc2", "none"]
    assert P.main([*holed, "--simulate", "2", "--out", str(tmp_path / "sim.csv")]) == 0  # the simulator: 2 drops
    assert "through-hole" not in capsys.readouterr().err


@pytest.mark.skipif(not (PARTS / "rect-a2.stl").is_file(), reason="no part library in parts/")
def test_predict_simulate_answers_with_the_simulator(tmp_path, capsys):
    """``--simulate 4``: the study's design with at most 4 drops (a grid below n0), its label in the
    part frame as a PMF that sums to 1, written like a model's answer."""
    from feeder.cli import main as cli

    out = tmp_path / "sim.csv"
    args = ["predict", "--part", str(PARTS / "rect-a2.stl"), "--loc1", "straight:30", "--loc2", "none"]
    assert cli([*args, "--simulate", "4", "--out", str(out)]) == 0
    frame = pd.read_csv(out)
    assert list(frame.columns) == ["angle_deg", "pmf", "cdf"] and len(frame) == 360
    assert frame["pmf"].sum() == pytest.approx(1.0) and frame["cdf"].iloc[-1] == pytest.approx(1.0)
    printed = capsys.readouterr()
    assert "simulated 4 drops (ok 4)" in printed.err and "(simulated): 1.00" in printed.out


@pytest.mark.skipif(not (PARTS / "rect-a2.stl").is_file(), reason="no part library in parts/")
def test_predict_simulate_audit_says_how_far_the_answer_may_be(tmp_path, capsys):
    """``--audit 4``: four drops more, the same answer, and its error estimate on stderr."""
    from feeder.cli import main as cli

    args = ["predict", "--part", str(PARTS / "rect-a2.stl"), "--loc1", "straight:30", "--loc2", "none"]
    outs = {k: tmp_path / f"{k}.csv" for k in ("plain", "audited")}
    assert cli([*args, "--simulate", "4", "--out", str(outs["plain"])]) == 0
    capsys.readouterr()
    assert cli([*args, "--simulate", "4", "--audit", "4", "--out", str(outs["audited"])]) == 0
    err = capsys.readouterr().err
    assert outs["plain"].read_bytes() == outs["audited"].read_bytes()  # the audit does not change the answer
    assert "4 audit drops more" in err and "upper estimates, feeder audit" in err


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--simulate", "1"], "at least 2 drops"),
        (["--simulate", "4", "--model", "analytic"], "not both"),
        (["--simulate", "4", "--audit", "1"], "at least 2 audit drops"),
        (["--audit", "4"], "give it with --simulate"),
    ],
)
def test_predict_simulate_refuses_bad_input_and_writes_nothing(tmp_path, capsys, extra, message):
    from feeder.cli import main as cli

    out = tmp_path / "sim.csv"
    args = ["predict", "--part", str(PARTS / "rect-a2.stl"), "--loc1", "straight:30", "--loc2", "none"]
    assert cli([*args, *extra, "--out", str(out)]) != 0
    assert message in capsys.readouterr().err and not out.exists()


def test_predict_simulate_with_every_drop_jammed_is_an_error_without_output(tmp_path, monkeypatch, capsys):
    """Nothing leaves the fences: no orientation to give, a one-line error, no file."""
    import feeder.sim.simulate as S
    from feeder.cli import main as cli

    monkeypatch.setattr(S, "simulate", fake_simulation({"straight30_none"}, drops=4))
    out = tmp_path / "sim.csv"
    args = ["predict", "--part", str(PARTS / "rect-a2.stl"), "--loc1", "straight:30", "--loc2", "none"]
    assert cli([*args, "--simulate", "4", "--out", str(out)]) != 0
    err = capsys.readouterr().err
    assert "none of the 4 drops left the fences lying flat (jammed 4; " in err and "ok mass 0" in err
    assert not out.exists()


def test_a_model_its_card_finds_worse_than_the_analytic_pmf_says_so(model_dir, tmp_path, capsys):
    """`--model models/m3`: its card's paired comparisons put it behind the analytic push PMF on new
    parts, and predict says so on stderr; a folder without a card (a `feeder train` output) says nothing."""
    from feeder.learn.export import worse_than_analytic

    row = {
        "baseline": "baseline_analytic_pmf",
        "metric": "cw1",
        "model": "mx",
        "split": "parts",
        "model_mean": 30.0,
        "baseline_mean": 20.0,
        "diff_mean": 10.0,
        "diff_low": 6.0,
        "diff_high": 14.0,
        "level": 0.95,
        "verdict": "worse",
    }
    even = {**row, "split": "test", "verdict": "no clear difference"}
    card = {"model": {"name": "mx"}, "metrics": {"model_vs_baselines": [row, even]}}
    note = worse_than_analytic(card)
    assert "new parts (Parts) 30.0° against 20.0° (+10.0° [6.0, 14.0], 95 % paired)" in note and "Test" not in note
    assert worse_than_analytic({"model": {"name": "mx"}, "metrics": {"model_vs_baselines": [even]}}) is None
    assert worse_than_analytic({"model": {"name": "other"}, "metrics": {"model_vs_baselines": [row]}}) is None
    assert worse_than_analytic({}) is None
    base = ["--features", str(model_dir / "p0.json"), "--loc1", "straight:30", "--loc2", "none"]
    assert P.main(["--model", str(model_dir / "m3"), *base, "--out", str(tmp_path / "a.csv")]) == 0
    assert "note:" not in capsys.readouterr().err
    P.choose_model(str(PARTS.parent / "models" / "m3"), "feeder predict", {"labels": {"bins": 360}})
    err = capsys.readouterr().err
    assert "note:" in err and "further from the simulator than the untrained analytic push PMF" in err


def test_recommend_says_when_the_symmetry_found_is_only_the_most_it_checks(tmp_path, capsys):
    """A 64-gon disc is reported as 12-fold, the most the check looks for: recommend says so."""
    from feeder.learn import recommend as R
    from feeder.parts.geometry import stl_bytes
    from feeder.parts.symmetry import DEFAULT_MAX_ORDER

    turn = np.linspace(0.0, 2 * np.pi, 64, endpoint=False)
    disc = tmp_path / "disc.stl"
    disc.write_bytes(stl_bytes(0.02 * np.c_[np.cos(turn), np.sin(turn)], 0.005, "disc"))
    assert R.symmetry_order("auto", disc) == DEFAULT_MAX_ORDER
    err = capsys.readouterr().err
    assert f"{DEFAULT_MAX_ORDER}-fold symmetric or more" in err and "--symmetry N" in err
    assert R.symmetry_order("auto", PARTS / "rect-a2.stl") == 2
    assert capsys.readouterr().err == ""
