"""Evaluation tables, baselines, GroupKFold and figures on a synthetic dataset."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from factories import small_overrides

from feeder.config import compose_config
from feeder.errors import FeederError
from feeder.labels.dataset import load_dataset
from feeder.learn import evaluate as E
from feeder.learn import train as T


@pytest.fixture(scope="module")
def trained(tmp_path_factory, regression_dataset):
    root = tmp_path_factory.mktemp("eval")
    ds = regression_dataset
    dirs = []
    for model in ("m3", "m7"):
        for seed in (0, 1):
            out = root / model / f"seed{seed}"
            T.train(compose_config("train", [*small_overrides(ds, out, model, epochs=3), f"seed={seed}"]))
            dirs.append(out)
    return root, ds, dirs


def test_summarise_uses_population_sd():
    m = {
        "r2": np.array([1.0, 0.5]),
        "w1": np.array(
            [
                10.0,
                20.0,
            ]
        ),
        "mse": np.array([0.1, 0.3]),
        "r2c": np.array([1.0, 0.8]),
        "cw1": np.array([4.0, 2.0]),
    }
    s = E.summarise(m)
    assert s == pytest.approx(
        {
            "n": 2,
            "r2_mean": 0.75,
            "r2_sd": 0.25,
            "w1_mean": 15.0,
            "w1_sd": 5.0,
            "mse_mean": 0.2,
            "r2c_mean": 0.9,
            "r2c_sd": 0.1,
            "cw1_mean": 3.0,
            "cw1_sd": 1.0,
        }
    )


def test_nearest_rows_with_leave_one_out():
    ref = np.array([[0.0, 0.0], [1.0, 0.0], [5.0, 5.0]])
    q = np.array([[0.1, 0.0], [4.0, 4.0], [0.0, 0.0]])
    assert list(E.nearest_rows(q, ref)) == [0, 2, 0]
    # the third query is reference row 0 itself: it must take its nearest other row
    assert list(E.nearest_rows(q, ref, exclude_same=np.array([-1, -1, 0]))) == [0, 2, 1]


def test_baselines_hand_check():
    pmf = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.5, 0.5, 0.0]])
    part = np.zeros((4, 45))
    part[:, 0] = [0.0, 1.0, 10.0, 0.9]
    feeder = np.tile([0, 1, 0, 30, 1, 0, 0, 0], (4, 1)).astype(float)
    data = {"pmf": pmf, "cdf": np.cumsum(pmf, 1), "part_raw": part, "feeder_raw": feeder}
    train = np.array([True, True, True, False])
    out = E.baseline_predictions(data, train)
    mean_cdf, _ = out[E.BASELINE_MEAN]
    assert np.allclose(mean_cdf[3], np.cumsum([1 / 3, 1 / 3, 1 / 3]))
    near, _ = out[E.BASELINE_NEAREST]
    # row 3 (x=0.9) -> training row 1; row 0 -> row 1 (not itself); row 2 -> row 1
    assert np.allclose(near[3], [0, 1, 1]) and np.allclose(near[0], [0, 1, 1]) and np.allclose(near[2], [0, 1, 1])
    assert np.allclose(near[1], [1, 1, 1])  # row 1 -> row 0
    assert list(out) == [E.BASELINE_MEAN, E.BASELINE_NEAREST] == E.baseline_names(data)  # no pmf_analytic
    # with the analytic PMF: its cumulative sum, row by row, and the other two unchanged
    analytic = np.array([[0.0, 0.5, 0.5], [0.2, 0.2, 0.6], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    out2 = E.baseline_predictions({**data, "pmf_analytic": analytic}, train)
    assert list(out2) == [E.BASELINE_MEAN, E.BASELINE_NEAREST, E.BASELINE_ANALYTIC]
    assert np.allclose(out2[E.BASELINE_ANALYTIC][0], [[0, 0.5, 1], [0.2, 0.4, 1], [1, 1, 1], [0, 0, 1]])
    assert np.array_equal(out2[E.BASELINE_NEAREST][0], near)


def test_combo_label():
    assert E.combo_label("curved10_curved20") == "curved-1 + curved-2"
    assert E.combo_label("none_curved45") == "curved-2 only"
    assert E.combo_label("straight30_none") == "straight-1 only"


def test_representative_rows_distinct_and_ordered():
    r2 = np.array([0.1, 0.9, 0.5, 0.7, 0.3, 0.95, 0.2])
    rows = E.representative_rows(r2)
    assert len(set(rows)) == 4
    assert list(np.argsort(-r2[rows])) == [0, 1, 2, 3]  # best to worst
    assert len(E.representative_rows(np.array([0.5, 0.6]))) == 2


def test_tables_files_and_values(trained, tmp_path):
    from feeder.labels.metrics import r2_cdf

    root, ds, dirs = trained
    written = E.write_tables(ds, dirs, tmp_path, {"resamples": 200, "level": 0.9, "seed": 3})
    data = load_dataset(ds)
    for number, split in ((5, "train"), (6, "test"), (7, "fences"), (8, "parts")):
        df = pd.read_csv(tmp_path / f"table{number}.csv")
        assert list(df.columns) == E.COLUMNS
        assert list(df.model) == ["m3", "m7", E.BASELINE_MEAN, E.BASELINE_NEAREST]
        assert (df.n == (data["split"] == split).sum()).all()
        assert (tmp_path / f"table{number}.md").read_text().startswith(f"Table {number}.")
        # the mean baseline's R² recomputed by hand
        mask = data["split"] == split
        mean_cdf = np.cumsum(data["pmf"][data["split"] == "train"].mean(0))
        want = r2_cdf(data["cdf"][mask], mean_cdf[None]).mean()
        assert df.set_index("model").loc[E.BASELINE_MEAN, "r2_mean"] == pytest.approx(want)
        assert (df.r2_sd >= 0).all() and (df.w1_mean > 0).all()
        # models: two seeds, the mean of the per-seed means and their spread; baselines: no seed
        by = df.set_index("model")
        assert by.loc["m3", "seeds"] == 2 and by.loc[E.BASELINE_MEAN, "seeds"] == 1
        assert np.isnan(by.loc[E.BASELINE_NEAREST, "r2_seed_sd"])
        from feeder.learn.models import TrainedModel

        seed_means = []
        for d in dirs[:2]:  # m3 seed 0 and seed 1
            _, cdf = TrainedModel.load(d).predict(data["part_raw"][mask], data["feeder_raw"][mask])
            seed_means.append(r2_cdf(data["cdf"][mask], cdf).mean())
        assert by.loc["m3", "r2_mean"] == pytest.approx(np.mean(seed_means))
        assert by.loc["m3", "r2_seed_sd"] == pytest.approx(np.std(seed_means, ddof=1))
        assert seed_means[0] != seed_means[1]  # the seeds really differ
    fences = pd.read_csv(tmp_path / "breakdown_fences.csv")
    assert set(fences.group) == {"curved-1 + curved-2"}
    parts = pd.read_csv(tmp_path / "breakdown_parts.csv")
    assert set(parts.group) == set(data["part"][data["split"] == "parts"])
    assert len(written) == 7
    paired = pd.read_csv(tmp_path / "model_vs_baselines.csv")
    assert list(paired.columns) == E.PAIRED_COLUMNS
    assert set(paired.split) == {"test", "fences", "parts"} and set(paired.model) == {"m3", "m7"}
    assert len(paired) == 3 * 2 * 2 * len(E.PAIRED_METRICS)
    # the paired difference is the seed-averaged model score minus the baseline's, per table
    t6 = pd.read_csv(tmp_path / "table6.csv").set_index("model")
    row = paired[(paired.split == "test") & (paired.model == "m3") & (paired.baseline == E.BASELINE_MEAN)]
    r2 = row[row.metric == "r2"].iloc[0]
    assert r2.model_mean == pytest.approx(t6.loc["m3", "r2_mean"])
    assert r2.baseline_mean == pytest.approx(t6.loc[E.BASELINE_MEAN, "r2_mean"])
    assert r2.diff_mean == pytest.approx(r2.model_mean - r2.baseline_mean)
    assert (paired.diff_low <= paired.diff_mean).all() and (paired.diff_mean <= paired.diff_high).all()


def test_paired_bootstrap_hand_cases():
    # a constant difference has a zero-width interval at the constant
    assert E.paired_bootstrap(np.full(7, 0.25), 100, 0.95, 0) == pytest.approx((0.25, 0.25, 0.25))
    # two units: every resampled mean is 0, 0.5 or 1 with probabilities 1/4, 1/2, 1/4
    mean, lo, hi = E.paired_bootstrap(np.array([0.0, 1.0]), 20000, 0.9, 1)
    assert mean == 0.5 and lo == 0.0 and hi == 1.0
    mean, lo, hi = E.paired_bootstrap(np.array([0.0, 1.0]), 20000, 0.4, 1)
    assert lo == hi == 0.5  # the central 40 % sit inside the middle half of the mass
    # seeded: the same call gives the same interval; against a plain loop of resamples
    diff = np.array([0.3, -0.1, 0.2, 0.05, 0.4, -0.2, 0.1])
    assert E.paired_bootstrap(diff, 500, 0.95, 7) == E.paired_bootstrap(diff, 500, 0.95, 7)
    rng = np.random.default_rng(7)
    idx = rng.integers(0, diff.size, size=(500, diff.size))
    loop = [np.mean([diff[j] for j in row]) for row in idx]
    assert E.paired_bootstrap(diff, 500, 0.95, 7)[1:] == pytest.approx(tuple(np.quantile(loop, [0.025, 0.975])))
    for bad in (np.array([]), np.array([np.nan, 1.0])):
        with pytest.raises(E.FeederError):
            E.paired_bootstrap(bad, 10, 0.95, 0)
    with pytest.raises(E.FeederError):
        E.paired_bootstrap(diff, 10, 1.0, 0)


def test_verdict_follows_the_metric_direction():
    assert E.verdict(0.01, 0.05, +1) == "better"  # R² up
    assert E.verdict(0.01, 0.05, -1) == "worse"  # W1 up
    assert E.verdict(-0.05, -0.01, -1) == "better"  # W1 down
    assert E.verdict(-0.05, -0.01, +1) == "worse"
    assert E.verdict(-0.01, 0.02, +1) == "no clear difference"
    assert E.verdict(0.0, 0.02, +1) == "no clear difference"  # touching zero is not excluding it


def test_seed_summary_hand_check():
    one = {
        "r2": np.array([1.0, 0.5]),
        "w1": np.array([10.0, 20.0]),
        "mse": np.array([0.1, 0.3]),
        "r2c": np.array([1.0, 0.5]),
        "cw1": np.array([4.0, 2.0]),
    }
    two = {k: v + 0.1 for k, v in one.items()}
    s = E.seed_summary([one, two], np.array([True, True]))
    assert s["seeds"] == 2 and s["n"] == 2
    assert s["r2_mean"] == pytest.approx(0.8) and s["r2_sd"] == pytest.approx(0.25)
    assert s["r2_seed_sd"] == pytest.approx(np.std([0.75, 0.85], ddof=1))
    assert np.isnan(E.seed_summary([one], np.array([True, False]))["cw1_seed_sd"])


def test_groupkfold_trains_one_model_per_fold(trained, tmp_path):
    root, ds, _ = trained
    data = load_dataset(ds)
    cfg = compose_config("train", small_overrides(ds, tmp_path / "unused", "m3", epochs=2))
    df, paired = E.groupkfold(
        data, cfg, seeds=[0, 1], progress=False, bootstrap={"resamples": 200, "level": 0.95, "seed": 0}
    )
    parts = sorted(set(data["part"]))
    assert (df[df.model == "m3"].seeds == 2).all() and (df[df.model == E.BASELINE_MEAN].seeds == 1).all()
    assert set(paired.split) == {"groupkfold over parts"} and (paired.n == len(parts)).all()
    over_m3 = df[(df.model == "m3") & (df.group == "over parts")].iloc[0]
    r2 = paired[(paired.metric == "r2") & (paired.baseline == E.BASELINE_MEAN)].iloc[0]
    assert r2.model_mean == pytest.approx(over_m3.r2_mean)
    for model in ("m3", E.BASELINE_MEAN, E.BASELINE_NEAREST):
        sub = df[df.model == model]
        assert list(sub.group) == [*parts, "all configurations", "over parts"]
        assert sub[sub.group == "all configurations"].n.item() == len(data["part"])
        over = sub[sub.group == "over parts"]
        assert over.r2_mean.item() == pytest.approx(sub[sub.group.isin(parts)].r2_mean.mean())
        assert np.isfinite(sub.r2_mean).all()


def test_groupkfold_never_trains_on_a_held_out_part(trained, tmp_path, monkeypatch):
    """Every row is predicted by a model (and baselines) fitted without any row of its part."""
    import feeder.learn.train as T

    root, ds, _ = trained
    data = load_dataset(ds)
    cfg = compose_config("train", small_overrides(ds, tmp_path / "unused", "m3", epochs=1))
    seen = {"fit": [], "baseline": []}
    real_fit, real_baselines = T.fit, E.baseline_predictions

    def spy_fit(cfg, data, train, **kw):
        seen["fit"].append(np.asarray(train).copy())
        return real_fit(cfg, data, train, **kw)

    def spy_baselines(data, train, prior_grids=None):
        seen["baseline"].append(np.asarray(train).copy())
        return real_baselines(data, train, prior_grids)

    monkeypatch.setattr(T, "fit", spy_fit)
    monkeypatch.setattr(E, "baseline_predictions", spy_baselines)
    E.groupkfold(data, cfg, seeds=[0, 1], progress=False)
    folds = np.unique(data["group_fold"])
    assert len(seen["fit"]) == 2 * folds.size and len(seen["baseline"]) == folds.size
    tested = np.zeros(len(data["part"]), dtype=int)
    for train, train_seed1, train_b in zip(seen["fit"][::2], seen["fit"][1::2], seen["baseline"], strict=True):
        np.testing.assert_array_equal(train, train_seed1)  # every seed of a fold trains on the same rows
        np.testing.assert_array_equal(train, train_b)
        held_out = ~train
        tested += held_out
        assert not set(data["part"][train]) & set(data["part"][held_out])
    assert (tested == 1).all()  # each row held out exactly once


def test_groupkfold_scores_each_row_with_the_model_that_held_it_out(trained, tmp_path, monkeypatch):
    """Each fold's model predicts exactly its held-out rows (not every row, which would let the
    last fold's model score everything)."""
    root, ds, _ = trained
    data = load_dataset(ds)
    cfg = compose_config("train", small_overrides(ds, tmp_path / "unused", "m3", epochs=1))
    seen = []  # (training rows, inputs that fold's model predicted)
    real_fit = T.fit

    def spy_fit(cfg, data, train, **kw):
        fitted = real_fit(cfg, data, train, **kw)
        real_predict = fitted.model.predict

        def spy_predict(part_raw, feeder_raw, *rest, **kw):
            seen.append((np.asarray(train).copy(), np.asarray(part_raw).copy()))
            return real_predict(part_raw, feeder_raw, *rest, **kw)

        fitted.model.predict = spy_predict
        return fitted

    monkeypatch.setattr(T, "fit", spy_fit)
    E.groupkfold(data, cfg, progress=False)
    assert len(seen) == np.unique(data["group_fold"]).size
    for train, predicted in seen:
        np.testing.assert_array_equal(predicted, data["part_raw"][~train])  # the held-out rows, only


def test_figure_data_and_figures(trained, tmp_path):
    from feeder.cli import main as cli
    from feeder.labels.metrics import r2_cdf

    root, ds, dirs = trained
    f12, f13 = tmp_path / "f12.npz", tmp_path / "f13.npz"
    assert (
        E.main(
            [
                "figure-data",
                "--dataset",
                str(ds),
                "--model",
                str(dirs[0]),
                "--fig12-data",
                str(f12),
                "--fig13-data",
                str(f13),
            ]
        )
        == 0
    )
    for data_file, split in ((f12, "Test"), (f13, "Parts")):
        with np.load(data_file) as z:
            assert str(z["split"]) == split and z["cdf_true"].shape == z["cdf_pred"].shape
            assert 1 <= len(z["part"]) <= len(E.FIGURE_QUANTILES)
            assert len(set(zip(z["part"], z["config_id"]))) == len(z["part"])  # distinct rows
            np.testing.assert_allclose(z["r2"], r2_cdf(z["cdf_true"], z["cdf_pred"]))
        png = tmp_path / f"{data_file.stem}.png"
        name = "fig12_test_predictions" if split == "Test" else "fig13_parts_predictions"
        assert cli(["figure", name, "--data", str(data_file), "--out", str(png)]) == 0
        assert png.read_bytes()[:4] == b"\x89PNG"


def test_grid_table(trained, tmp_path):
    root, ds, _ = trained
    for lr, bs in ((0.01, 16), (0.001, 32)):
        out = tmp_path / "grid" / f"lr{lr}_bs{bs}"
        extra = [f"model.lr={lr}", f"trainer.batch_size={bs}"]
        T.train(compose_config("train", small_overrides(ds, out, "m3", epochs=1, extra=extra)))
    df = E.grid_table(tmp_path / "grid")
    assert len(df) == 2 and set(df.batch_size) == {16, 32}
    assert df.best_val_loss.is_monotonic_increasing


def test_cli_tables(trained, tmp_path):
    root, ds, dirs = trained
    assert E.main(["tables", "--dataset", str(ds), "--models", *map(str, dirs), "--out-dir", str(tmp_path)]) == 0
    assert (tmp_path / "table8.md").is_file()


def _gkf(model, per_part, seed_sd=0.01):
    """A GroupKFold table of ``model`` and the mean-PMF baseline over parts a, b, c: per part
    (r2, r2c, cw1) of the model; the baseline 0.1 lower in R² and 2 degrees worse everywhere."""
    rows = []
    for name, shift, sd in ((model, 0.0, seed_sd), (E.BASELINE_MEAN, -0.1, np.nan)):
        vals = [(p, r2 + shift, r2c + shift, cw1 - 20.0 * shift) for p, (r2, r2c, cw1) in per_part.items()]
        for p, r2, r2c, cw1 in vals:
            rows.append({"model": name, "group": p, "n": 2, "r2_mean": r2, "r2c_mean": r2c, "cw1_mean": cw1})
        means = np.mean([v[1:] for v in vals], axis=0)
        rows.append({"model": name, "group": "all configurations", "n": 6, "r2_mean": 9, "r2c_mean": 9, "cw1_mean": 9})
        over = dict(zip(("r2_mean", "r2c_mean", "cw1_mean"), means, strict=True))
        rows.append({"model": name, "group": "over parts", "n": 3, **over, "r2_seed_sd": sd, "cw1_seed_sd": sd})
    return pd.DataFrame(rows)


def test_generalisation_table_by_hand():
    m3 = _gkf("m3", {"a": (0.8, 0.9, 30.0), "b": (0.6, 0.8, 40.0), "c": (0.7, 0.85, 35.0)})
    push = _gkf("m3push", {"a": (0.9, 0.95, 20.0), "b": (0.9, 0.95, 20.0), "c": (0.9, 0.95, 20.0)}, seed_sd=0.02)
    parts = pd.DataFrame(
        {"model": ["m3", E.BASELINE_MEAN], "r2_mean": [0.5, 0.4], "r2c_mean": [0.6, 0.5], "cw1_mean": [1.0, 2.0]}
    )
    boot = {"resamples": 200, "level": 0.95, "seed": 0}
    t = E.generalisation_table([m3, push], parts, boot).set_index("predictor")
    assert list(t.index) == ["m3", E.BASELINE_MEAN, "m3push"]  # the baseline once, from the first table
    assert t.loc["m3", "groupkfold_r2_mean"] == pytest.approx(0.7)
    assert t.loc["m3", "groupkfold_r2_sd_parts"] == pytest.approx(np.std([0.8, 0.6, 0.7]))
    assert t.loc["m3push", "groupkfold_r2_sd_seeds"] == 0.02 and np.isnan(t.loc["m3", "groupkfold_r2c_sd_seeds"])
    # every part 0.1 above the baseline in R² and 2 degrees better: a degenerate interval at the difference
    for metric, diff in (("r2", 0.1), ("r2c", 0.1), ("cw1", -2.0)):
        row = t.loc["m3"]
        assert (row[f"{metric}_vs_mean_pmf"], row[f"{metric}_vs_mean_pmf_low"], row[f"{metric}_vs_mean_pmf_high"]) == (
            pytest.approx((diff, diff, diff))
        )
        assert row[f"{metric}_verdict"] == "better"
    assert t.loc[E.BASELINE_MEAN, "r2_verdict"] == "" and t.loc[E.BASELINE_MEAN, "r2_vs_mean_pmf"] == 0.0
    assert t.loc["m3", "parts_split_r2_mean"] == 0.5 and np.isnan(t.loc["m3push", "parts_split_cw1_mean"])


def test_generalisation_needs_the_mean_baseline_and_the_same_parts():
    m3 = _gkf("m3", {"a": (0.8, 0.9, 30.0), "b": (0.6, 0.8, 40.0)})
    parts = pd.DataFrame({"model": ["m3"], "r2_mean": [0.5], "r2c_mean": [0.6], "cw1_mean": [1.0]})
    boot = {"resamples": 10, "level": 0.95, "seed": 0}
    with pytest.raises(FeederError, match="lack the baseline_mean_pmf rows"):
        E.generalisation_table([m3[m3.model == "m3"]], parts, boot)
    odd = m3[~((m3.model == E.BASELINE_MEAN) & (m3.group == "b"))]
    with pytest.raises(FeederError, match="cover different parts"):
        E.generalisation_table([odd], parts, boot)


def test_generalisation_cli_refuses_a_missing_table_in_one_line(tmp_path, capsys):
    from feeder.cli import main

    out = tmp_path / "g.csv"
    argv = [
        "evaluate",
        "generalisation",
        "--groupkfold",
        str(tmp_path / "no.csv"),
        "--parts-table",
        str(tmp_path / "t8.csv"),
    ]
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "GroupKFold table" in err and "is missing" in err and "\n" not in err and not out.exists()


def test_test_rows_with_a_training_neighbour_by_hand():
    from feeder.learn.evaluate import _split_note, fence_types, rows_with_a_neighbour

    assert fence_types("straight30_none") == "straight+none"
    data = {
        "part": np.array(["a", "a", "a", "b", "b"]),
        "config_id": np.array(
            ["straight30_none", "straight45_none", "curved30_none", "straight30_none", "none_straight30"]
        ),
        "split": np.array(["train", "test", "test", "train", "test"]),
    }
    # a's straight45_none shares straight+none with a training row; a's curved and b's none+straight do not
    assert rows_with_a_neighbour(data, "test") == (1, 3)
    assert (
        _split_note(data, "test")
        == "; 1 of 3 Test rows have a training row of the same part and fence-type combination"
    )
    assert _split_note(data, "fences") == ""
