import pandas as pd
import pytest

from feeder.errors import FeederError
from feeder.learn import generalisation_sets as GS
from feeder.learn.evaluate import BASELINE_MEAN, OVER_PARTS

BOOT = {"resamples": 200, "level": 0.95, "seed": 0}


def _table(model, per_part):
    """A GroupKFold table of one predictor: per-part rows (r2, r2c, cw1) and the summary rows."""
    rows = [
        {"model": model, "group": p, "r2_mean": r2, "r2c_mean": r2c, "cw1_mean": cw1}
        for p, (r2, r2c, cw1) in per_part.items()
    ]
    for group in ("all configurations", OVER_PARTS):
        rows.append({"model": model, "group": group, "r2_mean": -9.0, "r2c_mean": -9.0, "cw1_mean": -9.0})
    return pd.DataFrame(rows)


CONFIGS = pd.DataFrame(
    {
        "part": ["a", "a", "b", "w1", "w2"],
        "dataset": ["main", "main", "parts", "wide", "wide"],
    }
)


def test_sets_by_hand():
    base = _table(
        BASELINE_MEAN, {"a": (0.5, 0.6, 30.0), "b": (0.7, 0.8, 20.0), "w1": (0.4, 0.5, 40.0), "w2": (0.6, 0.7, 50.0)}
    )
    model = _table("m", {"a": (0.7, 0.6, 20.0), "b": (0.9, 0.8, 10.0), "w1": (0.3, 0.5, 40.0), "w2": (0.5, 0.7, 50.0)})
    df = GS.sets_table([pd.concat([model, base])], CONFIGS, BOOT).set_index(["predictor", "set"])
    assert list(df.loc["m"].index) == ["all", "protocol", "wide"]
    assert df.loc[("m", "protocol"), "parts"] == 2 and df.loc[("m", "wide"), "parts"] == 2
    # the summary rows (-9) are never averaged in
    assert df.loc[("m", "all"), "r2_mean"] == pytest.approx((0.7 + 0.9 + 0.3 + 0.5) / 4)
    assert df.loc[("m", "protocol"), "r2_mean"] == pytest.approx(0.8)
    assert df.loc[("m", "wide"), "cw1_mean"] == pytest.approx(45.0)
    # paired differences: +0.2 on both protocol parts, -0.1 on both wide parts (constant, so the interval is a point)
    assert df.loc[("m", "protocol"), "r2_vs_mean_pmf"] == pytest.approx(0.2)
    assert df.loc[("m", "protocol"), "r2_verdict"] == "better"
    assert df.loc[("m", "wide"), "r2_vs_mean_pmf_high"] == pytest.approx(-0.1)
    assert df.loc[("m", "wide"), "r2_verdict"] == "worse"
    assert df.loc[("m", "protocol"), "cw1_verdict"] == "better"  # lower W1 is better
    assert df.loc[("m", "wide"), "cw1_verdict"] == "no clear difference"
    assert df.loc[(BASELINE_MEAN, "all"), "r2_verdict"] == ""
    # a study without a wide library has no wide row
    only = GS.sets_table([base[base.group.isin(["a", "b", OVER_PARTS])]], CONFIGS[CONFIGS.dataset != "wide"], BOOT)
    assert list(only["set"]) == ["all", "protocol"]


def test_bad_inputs_are_one_line_errors():
    base = _table(BASELINE_MEAN, {"a": (0.5, 0.6, 30.0), "w1": (0.4, 0.5, 40.0)})
    with pytest.raises(FeederError, match="lack the baseline_mean_pmf"):
        GS.sets_table([_table("m", {"a": (0.5, 0.6, 30.0)})], CONFIGS, BOOT)
    with pytest.raises(FeederError, match="cover different parts"):
        GS.sets_table([base, _table("m", {"a": (0.5, 0.6, 30.0)})], CONFIGS, BOOT)
    with pytest.raises(FeederError, match="missing from the configuration table: zz"):
        GS.sets_table([_table(BASELINE_MEAN, {"zz": (0.5, 0.6, 30.0)})], CONFIGS, BOOT)
    both = pd.DataFrame({"part": ["a", "a"], "dataset": ["main", "wide"]})
    with pytest.raises(FeederError, match="part a is in the wide library and in the protocol"):
        GS.part_sets(both)


def test_cli_writes_csv_and_markdown(tmp_path, capsys):
    from feeder.cli import main as cli

    base = _table(
        BASELINE_MEAN, {"a": (0.5, 0.6, 30.0), "b": (0.7, 0.8, 20.0), "w1": (0.4, 0.5, 40.0), "w2": (0.6, 0.7, 50.0)}
    )
    base.to_csv(tmp_path / "gkf.csv", index=False)
    CONFIGS.to_csv(tmp_path / "configurations.csv", index=False)
    out = tmp_path / "tables" / "generalisation_by_set.csv"
    args = ["generalisation-sets", "--groupkfold", str(tmp_path / "gkf.csv"), "--configurations"]
    assert cli([*args, str(tmp_path / "configurations.csv"), "--out", str(out)]) == 0
    assert len(pd.read_csv(out)) == 3 and out.with_suffix(".md").read_text().startswith("Every predictor")
    capsys.readouterr()
    assert cli([*args, str(tmp_path / "nope.csv"), "--out", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err
    assert "nope.csv is missing" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x.csv").exists()


def test_one_table_per_model_each_repeating_the_baselines():
    """The workflow's layout: groupkfold_<model>.csv per model, each with the same baseline rows."""
    scores = {"a": (0.5, 0.6, 30.0), "b": (0.7, 0.8, 20.0), "w1": (0.4, 0.5, 40.0), "w2": (0.6, 0.7, 50.0)}
    base = _table(BASELINE_MEAN, scores)
    first = pd.concat([_table("m1", scores), base])
    second = pd.concat([_table("m2", {k: (v[0] + 0.1, v[1], v[2]) for k, v in scores.items()}), base])
    df = GS.sets_table([first, second], CONFIGS, BOOT)
    assert list(df.groupby("predictor", sort=False).size()) == [3, 3, 3]
    assert list(dict.fromkeys(df["predictor"])) == ["m1", BASELINE_MEAN, "m2"]
    m2 = df[df.predictor == "m2"].set_index("set")
    assert m2["r2_vs_mean_pmf"].to_numpy() == pytest.approx([0.1, 0.1, 0.1])
