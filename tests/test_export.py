"""`feeder export-model` and the shipped model that `feeder predict` / `feeder recommend` use
without --model, on a tiny trained model and synthetic evaluation tables."""

from __future__ import annotations

import hashlib
import io
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from factories import make_regression_dataset, small_overrides

from feeder.config import compose_config
from feeder.errors import FeederError
from feeder.io import write_npz
from feeder.labels.dataset import features_version, feeder_vector, load_dataset
from feeder.lane.fences import parse_location
from feeder.learn import export as E
from feeder.learn import inference
from feeder.learn import predict as P
from feeder.learn import recommend as R
from feeder.learn import train as T
from feeder.learn.evaluate import BASELINE_MEAN, BASELINE_NEAREST, BREAKDOWN_COLUMNS, COLUMNS, TABLES
from feeder.learn.models import SCALER_FILE, WEIGHTS_FILE, TrainedModel

ROOT = Path(__file__).resolve().parents[1]
PARTS = ROOT / "parts"
NAMES = ["m3", BASELINE_MEAN, BASELINE_NEAREST]
EXTRA = "extra_column"  # a column evaluate may add: the card copies every column
SEED_SD = "r2_seed_sd"
PAIRED = ["split", "model", "baseline", "metric", "diff_mean", "diff_low", "diff_high", "verdict"]
# an irregular pentagon (mm): no part of the library, no rotational symmetry
PENTAGON_MM = [(0.0, 0.0), (36.0, 0.0), (42.0, 17.0), (14.0, 28.0), (-5.0, 12.0)]
PENTAGON_THICKNESS_MM = 6.0


def plain(value):
    """A CSV cell as the card stores it (NaN -> None)."""
    if isinstance(value, np.generic):
        value = value.item()
    return None if isinstance(value, float) and math.isnan(value) else value


def csv_rows(path: Path, **where) -> list[dict]:
    df = pd.read_csv(path)
    for key, allowed in where.items():
        df = df[df[key].isin(allowed)]
    return [{k: plain(v) for k, v in row.items()} for row in df.to_dict(orient="records")]


def write_tables(out: Path, data: dict, seed: int = 0) -> None:
    """Tables 5-8, groupkfold_m3.csv and model_vs_baselines.csv as feeder evaluate lays them out,
    with random numbers, an extra column and an unrelated model (m1) that the card must skip."""
    rng = np.random.default_rng(seed)
    out.mkdir(parents=True, exist_ok=True)
    columns = [*COLUMNS, *([SEED_SD] if SEED_SD not in COLUMNS else []), EXTRA]
    for split, (number, _) in TABLES.items():
        n = int((data["split"] == split).sum())
        rows = []
        for name in ["m1", *NAMES]:
            row = {c: float(rng.normal()) for c in columns}
            row.update(model=name, n=n, **{EXTRA: f"note-{name}"})
            if name.startswith("baseline"):
                row[SEED_SD] = np.nan  # an empty cell
            rows.append(row)
        pd.DataFrame(rows, columns=columns).to_csv(out / f"table{number}.csv", index=False)
    rows = []
    for name in NAMES:
        for group in [*sorted(set(data["part"])), "all configurations", E.OVER_PARTS]:
            row = {c: float(rng.normal()) for c in [*BREAKDOWN_COLUMNS, "train_s"]}
            rows.append({**row, "model": name, "group": group, "n": 7})
    pd.DataFrame(rows).to_csv(out / "groupkfold_m3.csv", index=False)
    rows = [
        {
            "split": s,
            "model": m,
            "baseline": b,
            "metric": "r2",
            "diff_mean": float(rng.normal()),
            "diff_low": -1.0,
            "diff_high": 1.0,
            "verdict": "no clear difference",
        }
        for s in ("test", "parts")
        for m in ("m1", "m3")
        for b in (BASELINE_MEAN, BASELINE_NEAREST)
    ]
    pd.DataFrame(rows, columns=PAIRED).to_csv(out / E.MODEL_VS_BASELINES, index=False)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A trained m3 (seed 0), its dataset, evaluation tables and a provenance file."""
    root = tmp_path_factory.mktemp("export")
    make_regression_dataset(root / "ds.npz")
    T.train(compose_config("train", small_overrides(root / "ds.npz", root / "models" / "m3" / "seed0", "m3", epochs=2)))
    write_tables(root / "tables", load_dataset(root / "ds.npz"))
    sim = {"preset": "fast", "yaw_sampling": "adaptive", "drops": 64, "min_ok_drops": 10}
    provenance = {"git_commit": "abc123", "config_sha256": "f00d", "config": {"sim": sim}}
    (root / "provenance.json").write_text(json.dumps(provenance))
    return root


def export_args(run: Path, out: Path, provenance: bool = True) -> list[str]:
    args = ["--model", str(run / "models/m3/seed0"), "--tables", str(run / "tables"), "--dataset", str(run / "ds.npz")]
    args += ["--out", str(out)]
    return args + (["--provenance", str(run / "provenance.json")] if provenance else [])


def export(run: Path, out: Path, **kw) -> dict:
    return E.export_model(
        run / "models/m3/seed0", kw.get("tables", run / "tables"), run / "ds.npz", out, kw.get("provenance")
    )


@pytest.fixture(scope="module")
def shipped(run, tmp_path_factory):
    """An exported model folder (read-only for the tests)."""
    out = tmp_path_factory.mktemp("shipped") / "m3"
    assert E.main(export_args(run, out)) == 0
    return out


@pytest.fixture(scope="module")
def pentagon(tmp_path_factory):
    """A part written in the test, not one of the library's."""
    from feeder.parts.geometry import stl_bytes

    path = tmp_path_factory.mktemp("own_part") / "pentagon-export-test.stl"
    path.write_bytes(stl_bytes(np.array(PENTAGON_MM), PENTAGON_THICKNESS_MM, "pentagon"))
    assert not (PARTS / path.name).exists()
    return path


def snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def siblings(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.parent.iterdir())


# ---------------------------------------------------------------- export-model
def test_export_writes_the_model_files_and_both_cards(run, shipped):
    assert sorted(p.name for p in shipped.iterdir()) == sorted(
        [WEIGHTS_FILE, SCALER_FILE, E.CARD_FILE, E.CARD_MARKDOWN]
    )
    assert siblings(shipped) == ["m3"]  # no temporary folder left beside it
    for name in (WEIGHTS_FILE, SCALER_FILE):
        assert (shipped / name).read_bytes() == (run / "models/m3/seed0" / name).read_bytes()
    TrainedModel.load(shipped)
    card = json.loads((shipped / E.CARD_FILE).read_text())
    assert card["model"] == "m3" and card["seed"] == 0 and card["label_frame"] == "part"
    assert card["features_version"] == features_version() and len(card["inputs"]) == 53
    assert card["spec"]["name"] == "m3" and card["training"]["epochs_run"] >= 1
    data = load_dataset(run / "ds.npz")
    td = card["training_data"]
    assert td["rows"] == len(data["split"]) and td["rows_per_split"] == {
        s: int((data["split"] == s).sum()) for s in ("train", "test", "fences", "parts")
    }
    assert td["parts"] == len(set(data["part"])) == 5
    assert td["configurations"] == len(set(data["config_id"])) and td["bins"] == 360
    # the factory's dataset records no settings: the design comes from the provenance's config
    assert td["sim"] == {"preset": "fast", "yaw_sampling": "adaptive", "drops": 64}
    assert td["sim_source"] == "provenance" and card["provenance"] == {"git_commit": "abc123", "config_sha256": "f00d"}
    md = (shipped / E.CARD_MARKDOWN).read_text()
    assert md.startswith("# Model card: m3 (seed 0)") and card["features_version"] in md
    assert "sim.preset = fast" in md and "Unseen parts" in md and BASELINE_NEAREST in md
    for split in E.CARD_SPLITS:
        number, caption = TABLES[split]
        assert f"Table {number}. {caption}" in md


def test_the_card_says_what_the_model_reads_and_how_to_call_it(shipped):
    """Model 3's card: its 53 inputs and its --model folder; without --model the study answers
    (feeder.learn.study), which every card says. A model shipped beside it (models.ship) names its
    own inputs and folder."""
    card = json.loads((shipped / E.CARD_FILE).read_text())
    md = E.card_markdown(card)
    assert "feeder predict --model models/m3 --part my.stl" in md and "feeder recommend --model models/m3" in md
    assert "Without `--model` both answer from the study's own simulations (`models/study`)" in md
    assert E.CARD_INPUTS["paper"] in md
    other = {**card, "model": "m3pushonly", "spec": {**card["spec"], "inputs": "fence+push"}}
    md = E.card_markdown(other)
    assert E.CARD_INPUTS["fence+push"] in md and "Without `--model` both answer from the study's" in md
    assert "feeder predict --model models/m3pushonly --part my.stl" in md


def test_shipped_models_are_model_3_then_models_ship_each_with_its_tables():
    models = {"regression": ["m3", "m3push"], "groupkfold": ["m3", "m3push"], "ship": ["m3push", "m3"]}
    assert E.shipped_models(models) == ["m3", "m3push"]
    assert E.shipped_models({**models, "ship": []}) == ["m3"]
    for bad in ({**models, "groupkfold": ["m3"]}, {**models, "regression": ["m3"]}):
        with pytest.raises(FeederError, match="models.ship: m3push must also be in"):
            E.shipped_models(bad)


def test_card_metrics_are_the_table_rows(run, shipped):
    card = json.loads((shipped / E.CARD_FILE).read_text())
    metrics = card["metrics"]
    for split in E.CARD_SPLITS:
        path = run / "tables" / f"table{TABLES[split][0]}.csv"
        want = sorted(csv_rows(path, model=NAMES), key=lambda r: NAMES.index(r["model"]))
        assert metrics[split] == want  # every column, the numbers exactly
        assert [r["model"] for r in metrics[split]] == NAMES and all(EXTRA in r for r in metrics[split])
        assert metrics[split][1][SEED_SD] is None  # an empty cell
        assert isinstance(metrics[split][0]["r2_mean"], float) and metrics[split][0]["n"] > 0
    over = csv_rows(run / "tables/groupkfold_m3.csv", model=NAMES, group=[E.OVER_PARTS])
    assert metrics["unseen_parts"] == over and len(over) == 3
    paired = csv_rows(run / "tables" / E.MODEL_VS_BASELINES, model=["m3"])
    assert metrics["model_vs_baselines"] == paired and len(paired) == 4
    assert card["files"][WEIGHTS_FILE] == hashlib.sha256((shipped / WEIGHTS_FILE).read_bytes()).hexdigest()


def test_export_on_evaluates_own_tables(run, tmp_path):
    """The tables as `feeder evaluate tables` writes them for this model and dataset."""
    from feeder.learn.evaluate import write_tables as evaluate_tables

    evaluate_tables(run / "ds.npz", [run / "models/m3/seed0"], tmp_path / "tables")
    card = export(run, tmp_path / "out", tables=tmp_path / "tables")
    for split in E.CARD_SPLITS:
        want = csv_rows(tmp_path / "tables" / f"table{TABLES[split][0]}.csv", model=NAMES)
        assert card["metrics"][split] == sorted(want, key=lambda r: NAMES.index(r["model"]))
    assert card["metrics"]["unseen_parts"] is None
    assert card["training_data"]["sim"] is None and "not recorded" in (tmp_path / "out" / E.CARD_MARKDOWN).read_text()


def test_simulation_design_from_the_datasets_settings(run, tmp_path):
    data = dict(np.load(run / "ds.npz"))
    settings = {"sim": {"preset": "faithful", "yaw_sampling": "golden", "drops": 1000}, "labels": {"bins": 360}}
    write_npz(tmp_path / "ds.npz", **data, settings=np.array(json.dumps(settings)), label_frame=np.array("part"))
    card = E.export_model(
        run / "models/m3/seed0", run / "tables", tmp_path / "ds.npz", tmp_path / "out", run / "provenance.json"
    )
    assert card["training_data"]["sim"] == settings["sim"] and card["training_data"]["sim_source"] == "dataset"


def test_optional_tables_may_be_missing_the_split_tables_not(run, tmp_path):
    tables = tmp_path / "tables"
    tables.mkdir()
    for number in (6, 7, 8):
        (tables / f"table{number}.csv").write_bytes((run / "tables" / f"table{number}.csv").read_bytes())
    card = export(run, tmp_path / "a", tables=tables)
    assert card["metrics"]["unseen_parts"] is None and card["metrics"]["model_vs_baselines"] is None
    (tables / "table7.csv").unlink()
    with pytest.raises(FeederError, match="table7.csv is missing"):
        export(run, tmp_path / "b", tables=tables)
    assert not (tmp_path / "b").exists()


def test_tables_of_another_model_or_dataset_are_refused(run, tmp_path):
    tables = tmp_path / "tables"
    tables.mkdir()
    for number in (6, 7, 8):
        df = pd.read_csv(run / "tables" / f"table{number}.csv")
        if number == 8:
            df = df[df.model != "m3"]
        if number == 6:
            df["n"] += 1
        df.to_csv(tables / f"table{number}.csv", index=False)
    with pytest.raises(FeederError, match="do not belong together"):
        export(run, tmp_path / "a", tables=tables)
    df = pd.read_csv(run / "tables" / "table6.csv")
    df.to_csv(tables / "table6.csv", index=False)
    with pytest.raises(FeederError, match="table8.csv has no row for m3"):
        export(run, tmp_path / "a", tables=tables)


def test_export_replaces_an_earlier_export_but_nothing_else(run, tmp_path):
    out = tmp_path / "m3"
    export(run, out)
    (out / "stale.txt").write_text("from an older export")
    export(run, out, provenance=run / "provenance.json")
    assert not (out / "stale.txt").exists() and json.loads((out / E.CARD_FILE).read_text())["provenance"]
    assert siblings(out) == ["m3"]
    foreign = tmp_path / "results"
    foreign.mkdir()
    (foreign / "keep.txt").write_text("mine")
    with pytest.raises(FeederError, match="not an exported model folder"):
        export(run, foreign)
    assert (foreign / "keep.txt").read_text() == "mine"


def test_an_interrupted_export_leaves_the_previous_folder(run, tmp_path, monkeypatch):
    out = tmp_path / "m3"
    export(run, out)
    before = snapshot(out)

    def crash(*args, **kwargs):
        raise RuntimeError("power cut")

    with monkeypatch.context() as m:  # the crash just before the folder is put in place
        m.setattr(E, "replace_dir", crash)
        with pytest.raises(RuntimeError):
            export(run, out, provenance=run / "provenance.json")
    assert snapshot(out) == before and siblings(out) == ["m3"]
    with monkeypatch.context() as m:  # a writer fails half-way through the folder
        m.setattr("feeder.io.write_text", crash)
        with pytest.raises(RuntimeError):
            export(run, out, provenance=run / "provenance.json")
    assert snapshot(out) == before and siblings(out) == ["m3"]


def test_replacing_without_an_atomic_swap_moves_the_old_folder_back_on_failure(tmp_path, monkeypatch):
    """Where the system cannot swap two folders in one step (not Linux): move aside, rename."""
    monkeypatch.setattr(E, "_exchange", lambda a, b: False)
    out, new = tmp_path / "m3", tmp_path / ".m3.new.tmp"
    for folder, text in ((out, "old"), (new, "new")):
        folder.mkdir()
        (folder / E.CARD_FILE).write_text(text)
    real_rename = os.rename

    def rename(src, dst):
        if Path(src) == new:
            raise OSError(28, "No space left on device")
        real_rename(src, dst)

    monkeypatch.setattr(os, "rename", rename)
    with pytest.raises(OSError):
        E.replace_dir(new, out)
    assert (out / E.CARD_FILE).read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == [".m3.new.tmp", "m3"]  # nothing left aside
    monkeypatch.setattr(os, "rename", real_rename)
    E.replace_dir(new, out)
    assert (out / E.CARD_FILE).read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["m3"]


def test_the_export_command_is_registered(run, tmp_path, capsys):
    from feeder.cli import COMMANDS, main

    assert COMMANDS["export-model"][0] == "feeder.learn.export"
    assert main(["export-model", *export_args(run, tmp_path / "m3")]) == 0
    assert (tmp_path / "m3" / E.CARD_FILE).is_file() and "m3 (seed 0)" in capsys.readouterr().err
    assert main(["export-model", *export_args(run, tmp_path / "x")[:-2], "--dataset", str(tmp_path / "no.npz")]) == 2
    err = capsys.readouterr().err.strip()
    assert "no.npz" in err and "\n" not in err and not (tmp_path / "x").exists()


# ---------------------------------------------------------------- the features version
def test_features_version_follows_the_hand_bumped_number_and_the_inputs(monkeypatch):
    from feeder.labels import dataset as D

    v = features_version()
    assert v.startswith("1-") and v == features_version()
    monkeypatch.setattr(D, "FEATURES_VERSION", 2)
    assert features_version().startswith("2-") and features_version() != v
    monkeypatch.undo()
    monkeypatch.setattr(D, "INPUT_NAMES", tuple(reversed(D.INPUT_NAMES)))
    assert features_version() != v


def test_a_model_exported_for_other_features_is_refused(shipped, tmp_path, monkeypatch, capsys):
    from feeder.cli import main

    other = tmp_path / "m3"
    other.mkdir()
    for name, blob in snapshot(shipped).items():
        (other / name).write_bytes(blob)
    card = json.loads((other / E.CARD_FILE).read_text())
    (other / E.CARD_FILE).write_text(json.dumps({**card, "features_version": "0-000000000000"}))
    monkeypatch.setenv(E.MODEL_DIR_ENV, str(other))
    base = ["--features", str(tmp_path / "unused.json"), "--loc1", "none", "--loc2", "none"]
    with pytest.raises(FeederError, match="features version 0-000000000000"):
        P.main(base)
    with pytest.raises(FeederError, match="features version"):  # an explicit --model with a card too
        P.main(["--model", str(other), *base])
    argv = ["--features", "x.json", "--target", "0", "--tolerance", "5", "--symmetry", "1", "--configs", "none_none"]
    assert main(["recommend", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert "features version" in err and "\n" not in err


# ---------------------------------------------------------------- predict / recommend by default
def test_the_default_is_models_m3_at_the_repository_root(monkeypatch, capsys):
    import feeder

    monkeypatch.delenv(E.MODEL_DIR_ENV, raising=False)
    assert E.shipped_model_dir() == Path(feeder.__file__).resolve().parents[2] / "models" / "m3"
    assert E.shipped_model_dir() == ROOT / "models" / "m3"
    with pytest.raises(SystemExit):
        P.main(["--help"])
    assert "models/m3" in " ".join(capsys.readouterr().out.split())


def test_predict_uses_the_shipped_model_by_default(shipped, pentagon, tmp_path, monkeypatch, capsys):
    from feeder.parts.features import as_vector, features_of_file

    monkeypatch.setenv(E.MODEL_DIR_ENV, str(shipped))
    argv = ["--part", str(pentagon), "--loc1", "straight:30", "--loc2", "curved:20"]
    assert P.main([*argv, "--out", str(tmp_path / "pmf.csv")]) == 0
    assert f"the shipped model {shipped}" in capsys.readouterr().err
    part_raw = as_vector(features_of_file(pentagon))
    fv = feeder_vector(parse_location("straight:30"), parse_location("curved:20"))
    # predict answers with the numpy pass (feeder.learn.inference), in float64 on the saved weights
    pmf, cdf = inference.load(shipped).predict(part_raw[None], fv[None])
    df = pd.read_csv(tmp_path / "pmf.csv")
    assert len(df) == 360
    np.testing.assert_allclose(df.pmf, pmf[0], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(df.cdf, cdf[0], rtol=1e-12, atol=1e-15)
    # torch's float32 pass of the same weights: float32 rounding apart (tests/test_inference.py)
    torch_pmf, _ = TrainedModel.load(shipped).predict(part_raw[None], fv[None])
    np.testing.assert_allclose(df.pmf, torch_pmf[0], rtol=1e-4, atol=1e-9)
    assert P.main(argv) == 0  # the table on stdout
    printed = pd.read_csv(io.StringIO(capsys.readouterr().out))
    np.testing.assert_allclose(printed.pmf, pmf[0], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(printed.cdf, cdf[0], rtol=1e-12, atol=1e-15)


def test_recommend_uses_the_shipped_model_by_default(shipped, pentagon, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv(E.MODEL_DIR_ENV, str(shipped))
    ids = ["straight30_none", "curved45_straight20", "none_curved10"]
    argv = ["--part", str(pentagon), "--target", "90", "--tolerance", "15", "--configs", ",".join(ids)]
    assert R.main([*argv, "--out", str(tmp_path / "rank.csv")]) == 0
    assert "the shipped model" in capsys.readouterr().err
    ranked = pd.read_csv(tmp_path / "rank.csv")
    assert sorted(ranked.config_id) == sorted(ids) and ranked.probability.is_monotonic_decreasing
    model = TrainedModel.load(shipped)
    part_raw, frame_deg = P.part_vector(pentagon, None)
    for row in ranked.itertuples():
        frame = P.predict_frame(model, part_raw, row.loc1, row.loc2, frame_deg)
        want = R.window_probability(frame.pmf.to_numpy(), 90.0, 15.0, order=1)  # no symmetry
        assert row.probability == pytest.approx(want, abs=1e-12)


def test_an_explicit_model_still_wins(run, shipped, monkeypatch, tmp_path):
    monkeypatch.setenv(E.MODEL_DIR_ENV, str(tmp_path / "nowhere"))
    data = load_dataset(run / "ds.npz")
    raw = data["part_raw"][0].reshape(15, 3)
    feats = tmp_path / "p0.json"
    feats.write_text(
        json.dumps({"k": raw[:, 0].tolist(), "magnitude": raw[:, 1].tolist(), "phase": raw[:, 2].tolist()})
    )
    argv = ["--model", str(run / "models/m3/seed0"), "--features", str(feats), "--loc1", "none", "--loc2", "none"]
    assert P.main([*argv, "--out", str(tmp_path / "a.csv")]) == 0
    assert P.main(["--model", str(shipped), *argv[2:], "--out", str(tmp_path / "b.csv")]) == 0
    assert pd.read_csv(tmp_path / "a.csv").equals(pd.read_csv(tmp_path / "b.csv"))  # the same weights


def test_no_shipped_model_is_a_one_line_error(tmp_path, pentagon, capsys, monkeypatch):
    missing = tmp_path / "models" / "m3"
    env = {**os.environ, E.MODEL_DIR_ENV: str(missing)}
    proc = subprocess.run(
        [sys.executable, "-m", "feeder", "predict", "--part", str(pentagon), "--loc1", "none", "--loc2", "none"],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    err = proc.stderr.strip()
    assert proc.returncode == 2 and proc.stdout == "" and "Traceback" not in err and "\n" not in err
    assert "no shipped model" in err and str(missing) in err and "make run" in err and "--model" in err
    from feeder.cli import main

    monkeypatch.setenv(E.MODEL_DIR_ENV, str(missing))
    argv = ["--part", str(pentagon), "--target", "0", "--tolerance", "5", "--configs", "none_none"]
    assert main(["recommend", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("feeder recommend: error: no shipped model") and "\n" not in err
    missing.mkdir(parents=True)  # weights without a card: not an export
    (missing / WEIGHTS_FILE).write_bytes(b"")
    assert main(["predict", "--part", str(pentagon), "--loc1", "none", "--loc2", "none"]) == 2
    assert "feeder export-model" in capsys.readouterr().err


def test_the_card_headline_is_circular_w1_beside_the_analytic_and_mean_pmf():
    from feeder.learn.export import card_headline

    metrics = {
        "test": [
            {"model": "m9", "cw1_mean": 12.34},
            {"model": "baseline_mean_pmf", "cw1_mean": 30.0},
            {"model": "baseline_analytic_pmf", "cw1_mean": 10.0},
        ],
        "fences": [{"model": "m9", "cw1_mean": 40.0}],
        "parts": [],
        "unseen_parts": None,
    }
    line = card_headline("m9", metrics)
    assert line.startswith("Headline, circular W1 in degrees")
    assert line.endswith(": Test 12.3° (analytic PMF 10.0°, mean PMF 30.0°); Fences 40.0°.")
