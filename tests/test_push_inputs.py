"""The analytic push block as model inputs and as a baseline (issue #20 item 2).

* the dataset's ``push_raw`` / ``pmf_analytic`` against direct calls of the push module, in the
  label frame of the row's labels;
* ``model.inputs: paper+push`` models (train, save, load, predict) next to the paper's, which are
  bit for bit what they were before the option existed;
* the ``baseline_analytic_pmf`` rows of the evaluation tables;
* ``feeder predict`` / ``feeder recommend`` computing the push block from an STL part.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from factories import make_regression_dataset, small_overrides

from feeder.cli import main as cli
from feeder.config import compose_config
from feeder.errors import FeederError
from feeder.labels import dataset as D
from feeder.labels import metrics as L
from feeder.lane.fences import parse_config_id, parse_location
from feeder.learn import evaluate as E
from feeder.learn import predict as P
from feeder.learn import recommend as R
from feeder.learn import train as T
from feeder.learn.models import TrainedModel
from feeder.mechanics.distribution import analytic_distribution
from feeder.mechanics.features import PUSH_FEATURE_NAMES, push_block, push_features
from feeder.mechanics.fence import default_scene
from feeder.mechanics.hull import push_geometry
from feeder.mechanics.pmf import YAW_SNAP_DEG, analytic_pmf
from feeder.parts.geometry import load_outline, stl_bytes

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = Path(__file__).parent / "data" / "paper_models_golden.json"
SCENE = default_scene()
RECT_FRAME_DEG = 30.0  # the rectangle's file outline is turned by this: its principal frame is here
THICKNESS = 0.005
N_PUSH = len(PUSH_FEATURE_NAMES)


def rect(w, h):
    return np.array([(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)])


def turned(outline, deg):
    a = math.radians(deg)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    return np.asarray(outline) @ rot.T


RECT = rect(0.04, 0.02)
OUTLINES = {
    "rect": turned(RECT - RECT.mean(axis=0), RECT_FRAME_DEG),  # a 2:1 rectangle turned by 30 degrees
    "ell": np.array([(0, 0), (0.04, 0), (0.04, 0.01), (0.01, 0.01), (0.01, 0.03), (0, 0.03)], dtype=float),
    "tri": np.array([(0.0, 0.0), (0.03, 0.0), (0.015, 0.026)]),
}
FRAMES = {"rect": RECT_FRAME_DEG, "ell": 12.0, "tri": 200.0}
CONFIGS = ["straight30_none", "none_straight45", "curved40_straight20", "none_none"]


def settings(frame="principal", **extra):
    return {
        "sim": {"min_ok_mass": 0.5},
        "labels": {
            "bins": 360,
            "sigma_bins": 1.0,
            "levels_pct": [50, 100],
            "on_bad": "error",
            "frame": frame,
            "emulated_drops": 200,
        },
        "datasets": {"group_folds": 3},
        "scene": SCENE,
        **extra,
    }


def make_world(root: Path):
    """Part files, features (with frame_deg), simulation files and the configuration table of
    three parts in a few configurations; returns the table's path."""
    rng = np.random.default_rng(0)
    rows = []
    for part, outline in OUTLINES.items():
        (root / "parts").mkdir(parents=True, exist_ok=True)
        (root / "parts" / f"{part}.stl").write_bytes(stl_bytes(outline, THICKNESS, part))
        (root / "features").mkdir(exist_ok=True)
        feats = {
            "k": rng.integers(-10, 10, 15).tolist(),
            "magnitude": rng.random(15).tolist(),
            "phase": rng.uniform(-3, 3, 15).tolist(),
            "frame_deg": FRAMES[part],
        }
        (root / "features" / f"{part}.json").write_text(json.dumps(feats))
        for i, cid in enumerate(CONFIGS):
            path = root / "sim" / part / f"{cid}.npz"
            path.parent.mkdir(parents=True, exist_ok=True)
            drops = 40
            np.savez(
                path,
                final_yaw_deg=np.mod(rng.choice([30.0, 210.0], drops) + rng.normal(0, 5, drops), 360),
                initial_yaw_deg=rng.uniform(0, 360, drops),
                status=np.full(drops, "ok"),
                wall_s=np.float64(1.0),
                meta=np.array(json.dumps({"part": part, "config": cid})),
            )
            rows.append({"part": part, "config_id": cid, "dataset": "main", "split": ["train", "test"][i % 2]})
    csv = root / "configurations.csv"
    pd.DataFrame(rows).to_csv(csv, index=False)
    return csv


def build(root: Path, csv: Path, cfg: dict, out: str, parts_dir: Path | None = None) -> dict:
    argv = ["build", "--configurations", str(csv), "--features-dir", str(root / "features")]
    argv += ["--sim-dir", str(root / "sim"), "--settings", json.dumps(cfg), "--out", str(root / out)]
    if parts_dir is not None:
        argv += ["--parts-dir", str(parts_dir)]
    assert D.main(argv) == 0
    return D.load_dataset(root / out)


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    root = tmp_path_factory.mktemp("push_world")
    csv = make_world(root)
    principal = build(root, csv, settings(), "principal.npz", root / "parts")
    part = build(root, csv, settings("part"), "part.npz", root / "parts")
    return root, csv, principal, part


# ---------------------------------------------------------------------------------------------
# The dataset
# ---------------------------------------------------------------------------------------------
def test_dataset_push_block_equals_direct_calls_of_the_push_module(world):
    _, _, ds, _ = world
    n = len(ds["part"])
    assert ds["push_raw"].shape == (n, N_PUSH) and ds["pmf_analytic"].shape == (n, 360)
    assert tuple(ds["push_feature_names"]) == PUSH_FEATURE_NAMES
    np.testing.assert_allclose(ds["pmf_analytic"].sum(axis=1), 1.0)
    smooth = 1.0 * 360.0 / 360  # labels.sigma_bins in degrees
    for i in (0, 5, n - 1):
        part, (loc1, loc2) = ds["part"][i], parse_config_id(ds["config_id"][i])
        outline = load_outline(world[0] / "parts" / f"{part}.stl", "auto")
        frame = FRAMES[part]
        np.testing.assert_array_equal(ds["push_raw"][i], push_features(outline, loc1, loc2, SCENE, frame_deg=frame))
        want = analytic_pmf(outline, loc1, loc2, SCENE, frame_deg=frame, smooth_deg=smooth)
        np.testing.assert_array_equal(ds["pmf_analytic"][i], want)


def test_analytic_pmf_is_in_the_label_frame_of_the_row(world):
    """The rectangle's file outline is turned by 30 degrees and its principal frame is there: in
    the label frame its analytic PMF is the unturned rectangle's in that rectangle's own frame
    (where its simulated labels would peak, for the same body), and it is the analytic yaws moved
    by label_yaws, binned and smoothed like the labels."""
    _, _, ds, part_ds = world
    for cid in ("straight30_none", "none_straight45", "curved40_straight20"):
        i = int(np.flatnonzero((ds["part"] == "rect") & (ds["config_id"] == cid))[0])
        loc1, loc2 = parse_config_id(cid)
        unturned = analytic_pmf(RECT, loc1, loc2, SCENE, smooth_deg=1.0)
        np.testing.assert_allclose(ds["pmf_analytic"][i], unturned, atol=2e-3)
        assert np.argmax(ds["pmf_analytic"][i]) == np.argmax(unturned)
        # by hand: the part-frame yaws of the drops, through label_yaws, in 1-degree bins (snapped to
        # the push module's yaw grid first: 59.999999999 is 60) and smoothed like the labels
        dist = analytic_distribution(load_outline(world[0] / "parts" / "rect.stl", "auto"), loc1, loc2, SCENE)
        yaws = D.label_yaws(np.round(dist.yaws / YAW_SNAP_DEG) * YAW_SNAP_DEG, "principal", RECT_FRAME_DEG)
        hist = np.bincount(np.floor(yaws).astype(int) % 360, weights=dist.weights, minlength=360)
        np.testing.assert_allclose(ds["pmf_analytic"][i], L.wrapped_gaussian_smooth(hist, 1.0), atol=1e-9)
    # the part-frame dataset holds the same PMFs turned back by frame_deg, like its labels
    for i in range(len(ds["part"])):
        shift = FRAMES[ds["part"][i]]
        np.testing.assert_allclose(ds["pmf"][i], L.shift_pmf(part_ds["pmf"][i], shift), atol=1e-12)
        np.testing.assert_allclose(ds["pmf_analytic"][i], L.shift_pmf(part_ds["pmf_analytic"][i], shift), atol=1e-9)
    none = int(np.flatnonzero(ds["config_id"] == "none_none")[0])
    np.testing.assert_allclose(ds["pmf_analytic"][none], 1.0 / 360)  # no fence: uniform in any frame


def test_parts_dir_defaults_to_the_settings_and_without_one_there_is_no_push_block(world, tmp_path, caplog):
    root, csv, ds, _ = world
    via_settings = build(root, csv, settings(parts={"dir": str(root / "parts")}), "s.npz")
    np.testing.assert_array_equal(via_settings["push_raw"], ds["push_raw"])
    with caplog.at_level("WARNING"):
        old = build(root, csv, settings(), "none.npz")
    assert "no analytic push block" in caplog.text
    assert not set(D.PUSH_KEYS) & set(old) and E.baseline_names(old) == [E.BASELINE_MEAN, E.BASELINE_NEAREST]
    np.testing.assert_array_equal(old["pmf"], ds["pmf"])  # everything else is the same
    (tmp_path / "parts").mkdir()
    with pytest.raises(FeederError, match="ell.stl is missing") as err:
        build(root, csv, settings(), "x.npz", tmp_path / "parts")
    assert "\n" not in str(err.value)


def test_push_block_time_and_memo(world):
    """One pass per (part, configuration); the per-part memo of fence responses changes nothing."""
    root, _, ds, _ = world
    outline = load_outline(root / "parts" / "ell.stl", "auto")
    memo: dict = {}
    for cid in ("curved40_straight20", "straight30_none", "curved40_straight20"):
        loc1, loc2 = parse_config_id(cid)
        feats, pmf = push_block(outline, loc1, loc2, SCENE, frame_deg=12.0, pmf_smooth_deg=1.0, responses=memo)
        np.testing.assert_array_equal(feats, push_features(outline, loc1, loc2, SCENE, frame_deg=12.0))
        np.testing.assert_array_equal(pmf, analytic_pmf(outline, loc1, loc2, SCENE, frame_deg=12.0, smooth_deg=1.0))
    responses = [k for k in memo if k[0] != "arc_ride"]
    assert len(responses) == 3  # curved40 at loc1, straight20 at loc2, straight30 at loc1: the repeat adds none
    assert len(memo) == 4  # and the rides along curved40's arc (feeder.mechanics.arcride.arc_yaw)
    parts, cids = np.array(["ell", "ell"]), np.array(["straight30_none", "straight30_none"])
    raw, pmf, secs = D.push_arrays(parts, cids, {"ell": outline}, {"ell": 0.0}, SCENE, 360, 1.0)
    np.testing.assert_array_equal(raw[0], raw[1])
    np.testing.assert_array_equal(pmf[0], pmf[1])
    assert secs > 0


def test_push_block_over_worker_processes_is_bit_identical_to_one_process():
    """The dataset build spreads the push block over processes by part (threads.datasets_build); every
    row's features and PMF are those of one process, bit for bit, rows in their order (parts and
    configurations interleaved, a repeated row included); workers < 1 is refused in one line."""
    lib = Path(__file__).resolve().parents[1] / "parts"
    outlines = {name: load_outline(lib / f"{name}.stl", "auto") for name in ("rect-a2", "lshape-a", "gear12-a")}
    parts = np.array(["lshape-a", "rect-a2", "gear12-a", "lshape-a", "rect-a2", "lshape-a"])
    cids = np.array(
        [
            "curved40_straight20",
            "straight30_none",
            "none_curved30",
            "straight30_none",
            "straight30_none",
            "curved40_straight20",
        ]
    )
    frames = {"rect-a2": 0.0, "lshape-a": 17.0, "gear12-a": 5.0}
    one = D.push_arrays(parts, cids, outlines, frames, SCENE, 360, 1.0, workers=1)
    two = D.push_arrays(parts, cids, outlines, frames, SCENE, 360, 1.0, workers=2)
    np.testing.assert_array_equal(one[0], two[0])
    np.testing.assert_array_equal(one[1], two[1])
    np.testing.assert_array_equal(one[0][0], one[0][5])
    assert not np.array_equal(one[1][0], one[1][3])
    with pytest.raises(FeederError, match="workers must be >= 1") as err:
        D.push_arrays(parts, cids, outlines, frames, SCENE, 360, 1.0, workers=0)
    assert "\n" not in str(err.value)


def test_older_dataset_files_load_and_a_push_model_refuses_them_in_one_line(regression_dataset, tmp_path):
    data = D.load_dataset(regression_dataset)
    assert "push_raw" not in data
    overrides = small_overrides(regression_dataset, tmp_path / "m", "m3", 1, ["model.inputs=paper+push"])
    cfg = compose_config("train", overrides)
    with pytest.raises(FeederError, match="push_raw") as err:
        T.train(cfg)
    assert "\n" not in str(err.value) and not (tmp_path / "m" / "model.pt").exists()


def test_a_dataset_with_other_push_features_is_refused(push_regression_dataset, tmp_path):
    data = D.load_dataset(push_regression_dataset)
    data["push_feature_names"] = np.array(["x"] * N_PUSH)
    with pytest.raises(FeederError, match="push_feature_names"):
        D.raw_inputs(data, "paper+push")
    bad = {k: v for k, v in data.items() if k != "push_feature_names"}
    np.savez(tmp_path / "bad.npz", **bad)
    with pytest.raises(FeederError, match="go together"):
        D.load_dataset(tmp_path / "bad.npz")


# ---------------------------------------------------------------------------------------------
# Inputs and their version
# ---------------------------------------------------------------------------------------------
def test_input_names_and_features_version():
    assert D.input_names() == D.INPUT_NAMES and len(D.input_names("paper+push")) == 53 + N_PUSH
    assert D.input_names("paper+push")[53:] == tuple("push_" + n for n in PUSH_FEATURE_NAMES)
    # the paper's version is the one its models always had: the same content, hashed the same way
    blob = json.dumps(
        {"version": D.FEATURES_VERSION, "inputs": list(D.INPUT_NAMES), "dft": dataclasses.asdict(D.DFT)}, sort_keys=True
    )
    assert D.features_version() == f"{D.FEATURES_VERSION}-{hashlib.sha256(blob.encode()).hexdigest()[:12]}"
    assert D.features_version("paper+push") != D.features_version()
    assert D.features_version("paper+push").startswith(f"{D.FEATURES_VERSION}-")
    with pytest.raises(FeederError, match="model.inputs"):
        D.features_version("push")
    # without the DFT: the 8 fence inputs, then the push block, and a version of its own
    assert D.input_names("fence+push") == D.FEEDER_FEATURE_NAMES + D.input_names("paper+push")[53:]
    assert len({D.features_version(i) for i in D.INPUTS}) == 3


def test_push_scaler_fits_training_rows_only_and_round_trips(push_regression_dataset):
    data = D.load_dataset(push_regression_dataset)
    mask = data["split"] == "train"
    sc = D.fit_scaler(data["part_raw"], data["feeder_raw"], mask, data["push_raw"])
    np.testing.assert_allclose(sc.push_mean, data["push_raw"][mask].mean(axis=0))
    np.testing.assert_allclose(sc.push_std, data["push_raw"][mask].std(axis=0))
    x = sc.transform(data["part_raw"], data["feeder_raw"], data["push_raw"])
    paper = D.fit_scaler(data["part_raw"], data["feeder_raw"], mask)
    np.testing.assert_array_equal(x[:, :53], paper.transform(data["part_raw"], data["feeder_raw"]))
    np.testing.assert_allclose(x[mask, 53:].mean(axis=0), 0.0, atol=1e-12)
    assert set(paper.to_dict()) == {"mean", "std", "angle_min", "angle_max"}  # scaler.json as it was
    back = D.Scaler.from_dict(json.loads(json.dumps(sc.to_dict())))
    np.testing.assert_array_equal(back.transform(data["part_raw"], data["feeder_raw"], data["push_raw"]), x)
    with pytest.raises(FeederError, match="push"):
        sc.transform(data["part_raw"], data["feeder_raw"])
    # fence+push: the same scaled fence and push columns, the DFT columns left out
    no_dft = D.fit_scaler(data["part_raw"], data["feeder_raw"], mask, data["push_raw"], dft=False)
    assert no_dft.inputs == "fence+push" and no_dft.to_dict()["dft"] is False
    x_no_dft = no_dft.transform(data["part_raw"], data["feeder_raw"], data["push_raw"])
    np.testing.assert_array_equal(x_no_dft, x[:, 45:])
    back = D.Scaler.from_dict(json.loads(json.dumps(no_dft.to_dict())))
    assert back.inputs == "fence+push"
    np.testing.assert_array_equal(back.transform(data["part_raw"], data["feeder_raw"], data["push_raw"]), x_no_dft)
    with pytest.raises(FeederError, match="push block"):
        D.fit_scaler(data["part_raw"], data["feeder_raw"], mask, dft=False)


# ---------------------------------------------------------------------------------------------
# Models
# ---------------------------------------------------------------------------------------------
MODEL_RTOL = 1e-5  # float32 training, 2 epochs: AVX2 / AVX-512 / no-SIMD kernels differ by <= 1e-6
PINNED_ROWS = (0, -1)  # rows whose predictions the golden file stores in full


def _pinned(model_dir: Path, data: dict) -> dict:
    """sha256 of model.pt, scaler.json, the weights and every row's predictions; the predictions of
    two rows in full, and the mean PMF over all rows."""
    tm = TrainedModel.load(model_dir)
    pmf, cdf = tm.predict(data["part_raw"], data["feeder_raw"])
    pmf, cdf = np.ascontiguousarray(pmf, dtype=np.float64), np.ascontiguousarray(cdf, dtype=np.float64)
    h = hashlib.sha256()
    for k, v in tm.net.state_dict().items():
        h.update(k.encode())
        h.update(v.detach().cpu().numpy().tobytes())

    def sha(b: bytes) -> str:
        return hashlib.sha256(b).hexdigest()

    digests = {
        "model_pt": sha((model_dir / "model.pt").read_bytes()),
        "scaler_json": sha((model_dir / "scaler.json").read_bytes()),
        "weights": h.hexdigest(),
        "pmf": sha(pmf.tobytes()),
        "cdf": sha(cdf.tobytes()),
    }
    rows = list(PINNED_ROWS)
    full = {"pmf_rows": pmf[rows].tolist(), "cdf_rows": cdf[rows].tolist(), "pmf_mean": pmf.mean(0).tolist()}
    return {"sha256": digests, **full}


def _train_paper_model(tmp_path: Path, model: str, out: str, extra=()) -> tuple[dict, dict]:
    make_regression_dataset(tmp_path / "ds.npz")
    data = D.load_dataset(tmp_path / "ds.npz")
    T.train(compose_config("train", small_overrides(tmp_path / "ds.npz", tmp_path / out, model, 2, list(extra))))
    return _pinned(tmp_path / out, data), data


@pytest.mark.parametrize("model", ["m3", "m4"])
def test_paper_models_match_their_pin_from_before_model_inputs(tmp_path, model):
    """Weights, model.pt, scaler.json and predictions of a paper model (standard m3, branched m4)
    are those the code gave before ``model.inputs`` existed (same seed, CPU, one torch thread;
    tests/data/paper_models_golden.json): bit for bit under the arithmetic they were recorded with
    (tests/pins.py), the predictions within MODEL_RTOL elsewhere. A config without the key gives
    the same bits on this machine."""
    from pins import assert_pinned, same_arithmetic

    got, _ = _train_paper_model(tmp_path, model, "a")
    assert compose_config("train", [f"model={model}"]).model.inputs == "paper"
    golden = json.loads(GOLDEN.read_text())
    want, recorded_on = golden[model], golden["recorded_on"]
    for key in ("pmf_rows", "cdf_rows", "pmf_mean"):
        assert_pinned(got[key], want[key], recorded_on, MODEL_RTOL, 0.0, f"{model} {key}")
    if same_arithmetic(recorded_on):
        assert got["sha256"] == want["sha256"]
    without_key, _ = _train_paper_model(tmp_path, model, "b", ["~model.inputs"])
    assert without_key == got  # the same computation on the same machine: the same bits


@pytest.fixture(scope="module")
def push_models(tmp_path_factory, push_regression_dataset):
    root = tmp_path_factory.mktemp("push_models")
    ds = push_regression_dataset
    for model in ("m3", "m4"):  # a push variant has a name of its own in the tables
        extra = ["model.inputs=paper+push", f"model.name={model}push"]
        T.train(compose_config("train", small_overrides(ds, root / model, model, 3, extra)))
    T.train(compose_config("train", small_overrides(ds, root / "paper", "m3", 3)))
    T.train(compose_config("train", small_overrides(ds, root / "pushonly", "m3pushonly", 3)))
    return root, ds


def test_a_push_only_model_reads_the_fences_and_the_push_block_and_not_the_dft(push_models):
    root, ds = push_models
    data = D.load_dataset(ds)
    tm = TrainedModel.load(root / "pushonly")
    assert tm.inputs == "fence+push" and tm.needs_push and tm.spec.name == "m3pushonly"
    assert tm.net.body.net[0].in_features == 8 + N_PUSH
    pmf = tm.predict(data["part_raw"], data["feeder_raw"], data["push_raw"])[0]
    np.testing.assert_array_equal(tm.predict_rows(data)[0], pmf)
    # other DFT values change nothing; other push values or fences do
    np.testing.assert_array_equal(tm.predict(data["part_raw"] + 1.0, data["feeder_raw"], data["push_raw"])[0], pmf)
    assert not np.allclose(tm.predict(data["part_raw"], data["feeder_raw"], data["push_raw"] + 1.0)[0], pmf)
    card = json.loads((root / "pushonly" / "scaler.json").read_text())
    assert card["dft"] is False
    with pytest.raises(FeederError, match="push"):
        tm.predict(data["part_raw"], data["feeder_raw"])


def test_a_push_only_branched_model_is_refused():
    from feeder.learn.models import ModelSpec

    cfg = compose_config("train", ["model=m4", "model.inputs=fence+push"]).model
    with pytest.raises(ValueError, match="arch standard"):
        ModelSpec.from_config(cfg, 360)


def test_paper_push_models_train_save_load_and_predict(push_models):
    root, ds = push_models
    data = D.load_dataset(ds)
    std, br = TrainedModel.load(root / "m3"), TrainedModel.load(root / "m4")
    assert std.inputs == br.inputs == "paper+push" and std.needs_push
    assert std.net.body.net[0].in_features == 53 + N_PUSH
    # branched: the push block goes to the feeder branch, the part branch keeps the 45 DFT values
    assert br.net.body.part[0].in_features == 45 and br.net.body.feeder[0].in_features == 8 + N_PUSH
    scaler = json.loads((root / "m3" / "scaler.json").read_text())
    mask = data["split"] == "train"
    np.testing.assert_allclose(scaler["push_mean"], data["push_raw"][mask].mean(axis=0))
    metrics = json.loads((root / "m3" / "metrics.json").read_text())
    assert np.isfinite(metrics["r2_test"])
    for tm in (std, br):
        pmf, cdf = tm.predict_rows(data)
        assert pmf.shape == (len(data["part"]), 360) and np.allclose(pmf.sum(axis=1), 1.0)
        np.testing.assert_array_equal(pmf, tm.predict(data["part_raw"], data["feeder_raw"], data["push_raw"])[0])
        with pytest.raises(FeederError, match="push") as err:
            tm.predict(data["part_raw"], data["feeder_raw"])
        assert "\n" not in str(err.value)
        # the push block is an input: other push values, other predictions
        assert not np.allclose(tm.predict(data["part_raw"], data["feeder_raw"], data["push_raw"] + 1.0)[0], pmf)
    paper = TrainedModel.load(root / "paper")
    assert paper.inputs == "paper" and not paper.needs_push
    np.testing.assert_array_equal(paper.predict_rows(data)[0], paper.predict(data["part_raw"], data["feeder_raw"])[0])


def test_a_push_model_of_other_push_features_is_refused(push_models, tmp_path, monkeypatch):
    root, _ = push_models
    monkeypatch.setattr("feeder.mechanics.features.PUSH_FEATURE_NAMES", PUSH_FEATURE_NAMES + ("extra",))
    with pytest.raises(FeederError, match="retrain") as err:
        TrainedModel.load(root / "m3")
    assert "\n" not in str(err.value)


# ---------------------------------------------------------------------------------------------
# The analytic baseline
# ---------------------------------------------------------------------------------------------
def test_analytic_baseline_hand_check():
    pmf = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    analytic = np.array([[0.5, 0.5, 0.0], [0.0, 1.0, 0.0], [0.2, 0.2, 0.6]])
    data = {
        "pmf": pmf,
        "cdf": np.cumsum(pmf, 1),
        "part_raw": np.arange(135.0).reshape(3, 45),
        "feeder_raw": np.tile([0, 1, 0, 30, 1, 0, 0, 0], (3, 1)).astype(float),
        "pmf_analytic": analytic,
    }
    out = E.baseline_predictions(data, np.array([True, True, False]))
    assert list(out) == [E.BASELINE_MEAN, E.BASELINE_NEAREST, E.BASELINE_ANALYTIC]
    cdf, secs = out[E.BASELINE_ANALYTIC]
    np.testing.assert_allclose(cdf, [[0.5, 1.0, 1.0], [0.0, 1.0, 1.0], [0.2, 0.4, 1.0]])  # no training row read
    assert secs >= 0.0


def test_analytic_baseline_rows_in_every_table(push_models, tmp_path):
    from feeder.labels.metrics import r2_cdf

    root, ds = push_models
    dirs = [root / "m3", root / "paper"]
    E.write_tables(ds, dirs, tmp_path, {"resamples": 50, "level": 0.9, "seed": 0})
    data = D.load_dataset(ds)
    for number, split in ((5, "train"), (6, "test"), (7, "fences"), (8, "parts")):
        df = pd.read_csv(tmp_path / f"table{number}.csv").set_index("model")
        assert list(df.index) == ["m3push", "m3", E.BASELINE_MEAN, E.BASELINE_NEAREST, E.BASELINE_ANALYTIC]
        mask = data["split"] == split
        want = r2_cdf(data["cdf"][mask], np.cumsum(data["pmf_analytic"][mask], axis=1)).mean()
        assert df.loc[E.BASELINE_ANALYTIC, "r2_mean"] == pytest.approx(want)
        assert df.loc[E.BASELINE_ANALYTIC, "seeds"] == 1
    for split in ("fences", "parts"):
        assert E.BASELINE_ANALYTIC in set(pd.read_csv(tmp_path / f"breakdown_{split}.csv").model)
    paired = pd.read_csv(tmp_path / "model_vs_baselines.csv")
    assert set(paired.baseline) == {E.BASELINE_MEAN, E.BASELINE_NEAREST, E.BASELINE_ANALYTIC}
    assert len(paired) == 3 * 2 * 3 * len(E.PAIRED_METRICS)  # splits x models x baselines x metrics
    row = paired[(paired.split == "parts") & (paired.model == "m3push") & (paired.baseline == E.BASELINE_ANALYTIC)]
    r2 = row[row.metric == "r2"].iloc[0]
    t8 = pd.read_csv(tmp_path / "table8.csv").set_index("model")
    assert r2.baseline_mean == pytest.approx(t8.loc[E.BASELINE_ANALYTIC, "r2_mean"])
    assert r2.diff_mean == pytest.approx(r2.model_mean - r2.baseline_mean)


def test_groupkfold_compares_with_the_analytic_baseline(push_models):
    _, ds = push_models
    data = D.load_dataset(ds)
    cfg = compose_config("train", small_overrides(ds, "unused", "m3", 1, ["model.inputs=paper+push"]))
    bootstrap = {"resamples": 20, "level": 0.9, "seed": 0}
    table, paired = E.groupkfold(data, cfg, seeds=[0], progress=False, bootstrap=bootstrap)
    over = table[table.group == "over parts"].set_index("model")
    assert E.BASELINE_ANALYTIC in over.index and E.BASELINE_PRIOR in over.index  # the config has a prior node
    assert set(paired.baseline) == {E.BASELINE_MEAN, E.BASELINE_NEAREST, E.BASELINE_ANALYTIC, E.BASELINE_PRIOR}


# ---------------------------------------------------------------------------------------------
# feeder predict / recommend
# ---------------------------------------------------------------------------------------------
STL = ROOT / "parts" / "rect-a2.stl"


@pytest.mark.skipif(not STL.is_file(), reason="no part library in parts/")
def test_predict_with_a_push_model_computes_the_push_block_of_the_stl(push_models, tmp_path, capsys):
    from feeder.parts.features import as_vector, features_of_file

    root, _ = push_models
    out = tmp_path / "pmf.csv"
    argv = ["--model", str(root / "m4"), "--part", str(STL), "--loc1", "straight:30", "--loc2", "curved:40"]
    assert P.main([*argv, "--out", str(out)]) == 0
    assert "push features" in capsys.readouterr().err
    got = pd.read_csv(out)
    tm = P.load_model(root / "m4")  # what predict answers with: the network in numpy
    assert tm.label_frame == "part"  # the synthetic dataset: push features in the part frame
    push = push_features(load_outline(STL, "auto"), "straight:30", "curved:40", SCENE)
    feeder = D.feeder_vector(parse_location("straight:30"), parse_location("curved:40"))
    pmf, _ = tm.predict(as_vector(features_of_file(STL)), feeder, push)
    np.testing.assert_allclose(got.pmf, pmf[0], atol=1e-12)


def test_predict_with_a_push_model_and_features_alone_is_a_one_line_error(push_models, tmp_path, capsys):
    root, ds = push_models
    raw = D.load_dataset(ds)["part_raw"][0].reshape(15, 3)
    feats = tmp_path / "p.json"
    feats.write_text(
        json.dumps({"k": raw[:, 0].tolist(), "magnitude": raw[:, 1].tolist(), "phase": raw[:, 2].tolist()})
    )
    argv = ["--model", str(root / "m3"), "--features", str(feats), "--loc1", "straight:30", "--loc2", "none"]
    with pytest.raises(FeederError, match="--part PART.stl") as err:
        P.main([*argv, "--out", str(tmp_path / "x.csv")])
    assert "\n" not in str(err.value) and not (tmp_path / "x.csv").exists()
    assert cli(["predict", *argv]) == 2
    msg = capsys.readouterr().err.strip()
    assert "paper+push" in msg and "\n" not in msg
    xyz = ROOT / "parts" / "blob-a.xyz"
    if xyz.is_file():  # a face point cloud has no outline either
        with pytest.raises(FeederError, match="--part PART.stl"):
            P.main(["--model", str(root / "m3"), "--part", str(xyz), "--loc1", "none", "--loc2", "none"])
    rec = ["--model", str(root / "m3"), "--features", str(feats), "--target", "0", "--tolerance", "5"]
    assert cli(["recommend", *rec, "--symmetry", "1", "--configs", "none_none"]) == 2
    assert "--part PART.stl" in capsys.readouterr().err


@pytest.mark.skipif(not STL.is_file(), reason="no part library in parts/")
def test_recommend_with_a_push_model_ranks_with_each_configurations_push_block(push_models, tmp_path):
    from feeder.parts.features import as_vector, features_of_file

    root, _ = push_models
    configs = ["straight30_none", "none_straight45"]
    out = tmp_path / "rank.csv"
    argv = ["--model", str(root / "m3"), "--part", str(STL), "--target", "90", "--tolerance", "10"]
    assert R.main([*argv, "--symmetry", "1", "--configs", ",".join(configs), "--out", str(out)]) == 0
    ranked = pd.read_csv(out).set_index("config_id")
    tm = TrainedModel.load(root / "m3")
    outline = load_outline(STL, "auto")
    for cid in configs:
        loc1, loc2 = parse_config_id(cid)
        push = push_features(outline, loc1, loc2, SCENE)
        pmf, _ = tm.predict(as_vector(features_of_file(STL)), D.feeder_vector(loc1, loc2), push)
        assert ranked.loc[cid, "probability"] == pytest.approx(R.window_probability(pmf[0], 90.0, 10.0)[()])


def test_the_card_check_compares_the_version_of_the_models_own_inputs(tmp_path):
    """A paper+push model's card records the push version; the paper version is not enough for
    it, and a paper model's card (no inputs in its spec) is checked against the paper version."""
    from feeder.learn import export as E

    def card(inputs, version):
        spec = {"name": "m3"} if inputs is None else {"name": "m3", "inputs": inputs}
        (tmp_path / E.CARD_FILE).write_text(json.dumps({"spec": spec, "features_version": version}))

    card("paper+push", D.features_version("paper+push"))
    E.check_card(tmp_path)
    card("paper+push", D.features_version("paper"))
    with pytest.raises(FeederError, match="features version"):
        E.check_card(tmp_path)
    card(None, D.features_version("paper"))
    E.check_card(tmp_path)
    card("paper+cake", D.features_version("paper"))
    with pytest.raises(FeederError, match="unknown model inputs 'paper\\+cake'"):
        E.check_card(tmp_path)


def test_the_dataset_push_block_sees_a_parts_holes(tmp_path):
    """The plate's hole sits off-centre, so its centre of mass is not the outline's: the push block
    from its STL is that of the outline less the hole, not of the solid outline."""
    from feeder.lane.fences import config_id, parse_location
    from feeder.mechanics.fence import default_scene
    from feeder.parts.geometry import stl_bytes
    from feeder.parts.shapes import shape_part

    plate = shape_part("plate-60x30x10", 0.005)
    (tmp_path / "plate.stl").write_bytes(stl_bytes(plate.outline, 0.005, "plate", holes=plate.holes))
    profiles = D._part_outlines(["plate"], tmp_path, "m")
    outline, holes = profiles["plate"]
    assert len(holes) == 1
    cid = np.array([config_id(parse_location("straight:30"), parse_location("none"))])
    args = (np.array(["plate"]), cid)
    rest = ({"plate": 0.0}, default_scene(), 360, 2.0)
    holed, _, _ = D.push_arrays(*args, profiles, *rest)
    solid, _, _ = D.push_arrays(*args, {"plate": outline}, *rest)
    direct = push_features(
        push_geometry(outline, holes),
        *(parse_location(s) for s in ("straight:30", "none")),
        default_scene(),
        frame_deg=0.0,
        bins=360,
    )
    np.testing.assert_allclose(holed[0], direct)
    assert not np.allclose(holed, solid)


if __name__ == "__main__":  # re-pin: write tests/data/paper_models_golden.json
    import tempfile

    from pins import arithmetic

    golden = {
        "_about": "Paper (53-input) models m3 (standard) and m4 (branched) trained before model.inputs existed: "
        "tests/factories.make_regression_dataset() defaults, small_overrides(..., epochs=2), seed 0, CPU, one thread. "
        "sha256 of model.pt, scaler.json, the state_dict tensors (name + float32 bytes, in order) and the float64 "
        "post-processed predictions of every row; pmf_rows / cdf_rows: the predictions of rows "
        f"{PINNED_ROWS} in full; pmf_mean: the mean PMF over all rows; recorded_on: the arithmetic of the "
        "recording process (tests/pins.py)",
        "recorded_on": arithmetic("numpy", "torch"),
    }
    for model in ("m3", "m4"):
        golden[model] = _train_paper_model(Path(tempfile.mkdtemp()), model, "a")[0]
    GOLDEN.write_text(json.dumps(golden, indent=1) + "\n")
