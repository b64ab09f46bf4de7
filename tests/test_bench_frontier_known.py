"""feeder bench-frontier-known (issue #39 item 4): every answer for a known part at a new angle."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from feeder.bench import frontier_known as K
from feeder.cli import main as cli
from feeder.errors import FeederError

PARTS_DIR = "parts"


def _settings(**known):
    from feeder.config import load_study_config

    cfg = load_study_config("config/config.yaml")
    fk = {"configurations": 2, "budgets": [4], "models": [], "seed": 1, "repeats": 1, "resamples": 200} | known
    cfg["sim"]["frontier_known"] = fk
    return {k: cfg[k] for k in ("scene", "sim", "labels", "parts", "models")}


def test_check_frontier_known_refuses_bad_settings():
    assert K.check_frontier_known(_settings())["budgets"] == [4]
    for bad, match in (
        ({"budgets": [1]}, "at least 2 drops"),
        ({"budgets": []}, "at least 2 drops"),
        ({"configurations": 0}, "configurations must be at least 1"),
        ({"repeats": 0}, "at least 1"),
        ({"seed": -4, "budgets": [4]}, "reuse the study's base seed"),  # -4 + 4 = sim.base_seed 0
    ):
        with pytest.raises(FeederError, match=match):
            K.check_frontier_known(_settings(**bad))
    settings = _settings()
    del settings["sim"]["frontier_known"]["budgets"]
    with pytest.raises(FeederError, match="lacks or mistypes sim.frontier_known"):
        K.check_frontier_known(settings)


def test_the_replicates_never_use_the_study_seed_and_differ_by_budget():
    assert [K.replicate_seed(1, b) for b in (8, 16, 32, 40)] == [9, 17, 33, 41]


def test_pick_rows_depends_on_the_ids_alone():
    parts = np.array(["a", "a", "b", "b", "c", "c"])
    cids = np.array(["x", "y", "x", "y", "x", "y"])
    some = K.pick_rows(parts, cids, [0, 1, 2, 3], 2, seed=1)
    assert some.size == 2 and np.all(np.diff(some) > 0) and set(some) <= {0, 1, 2, 3}
    assert np.array_equal(some, K.pick_rows(parts, cids, [0, 1, 2, 3], 2, seed=1))  # seeded
    # the same rows when another row joins, unless it ranks before them
    more = K.pick_rows(parts, cids, [0, 1, 2, 3, 4, 5], 6, seed=1)
    assert set(some) <= set(more)
    assert not all(np.array_equal(some, K.pick_rows(parts, cids, [0, 1, 2, 3], 2, seed=s)) for s in range(2, 12))


def test_scores_by_hand_across_zero():
    a, b = np.zeros(360), np.zeros(360)
    a[359], b[1] = 1.0, 1.0  # 359.5 and 1.5 degrees: 2 degrees apart across 0
    got = K.scores(a, b)
    assert got["circular_w1_deg"] == pytest.approx(2.0)
    assert got["sup_cdf"] == pytest.approx(1.0)
    c = np.zeros(360)
    c[[10, 20]] = 0.5  # half the mass 10 degrees away
    assert K.scores(c, np.eye(360)[10])["circular_w1_deg"] == pytest.approx(5.0)


def test_summary_pairs_the_structured_predictor_with_each_answer():
    rows = []
    for k, (ours, theirs, simulated) in enumerate(((2.0, 5.0, True), (4.0, 4.0, True), (6.0, 12.0, False))):
        for answer, w1 in (("structured", ours), ("analytic", theirs)):
            rows.append(
                {"config": f"c{k}", "answer": answer, "kind": "predictor", "budget": 0, "simulated": simulated}
                | {"cpu_s": 0.5, "circular_w1_deg": w1, "sup_cdf": w1 / 100}
            )
    rows.append(
        {"config": "c0", "answer": "simulate8", "kind": "simulate", "budget": 8, "simulated": True}
        | {"cpu_s": 3.0, "circular_w1_deg": 1.0, "sup_cdf": 0.01}
    )
    table = K.summary(pd.DataFrame(rows), resamples=500, seed=0).set_index(["configurations", "answer"])
    assert table.loc[("test", "analytic"), "n"] == 3 and ("test", "simulate8") not in table.index  # predictors only
    assert table.loc[("test", "analytic"), "diff"] == pytest.approx((-3.0 + 0.0 - 6.0) / 3)
    assert table.loc[("all", "analytic"), "diff"] == pytest.approx(-1.5)  # the two simulated configurations
    assert table.loc[("all", "analytic"), "circular_w1_deg"] == pytest.approx(4.5)
    assert table.loc[("all", "simulate8"), "diff"] == pytest.approx(2.0 - 1.0)  # paired on c0 alone
    assert np.isnan(table.loc[("all", "structured"), "diff"])
    low, high = table.loc[("test", "analytic"), ["diff_low", "diff_high"]]
    assert low <= -3.0 <= high


def test_summary_leaves_out_answers_without_a_score_and_counts_the_timed():
    rows = [
        {"config": f"c{k}", "answer": a, "kind": "predictor", "budget": 0, "simulated": True}
        | {"cpu_s": cpu, "circular_w1_deg": w1, "sup_cdf": 0.1}
        for k, (a, cpu, w1) in enumerate(
            (("structured", 0.5, 2.0), ("structured", np.nan, 3.0), ("analytic", 0.1, np.nan), ("analytic", 0.1, 5.0))
        )
    ]
    rows[2]["config"], rows[3]["config"] = "c0", "c1"
    table = K.summary(pd.DataFrame(rows), resamples=200, seed=0).set_index(["configurations", "answer"])
    analytic, ours = table.loc[("all", "analytic")], table.loc[("all", "structured")]
    assert analytic["n"] == 1 and analytic["circular_w1_deg"] == 5.0  # c0's score is missing
    assert analytic["diff"] == pytest.approx(3.0 - 5.0)  # paired on c1 alone
    assert ours["n"] == 2 and ours["n_timed"] == 1 and ours["cpu_s_mean"] == 0.5


def test_a_kept_file_is_reused_only_for_the_same_part_bytes_and_code(tmp_path):
    settings = _settings()
    stl = tmp_path / "p.stl"
    stl.write_bytes(open(f"{PARTS_DIR}/rect-a3.stl", "rb").read())
    first = K.replicate_request(stl, 8, 9, settings)
    assert K.replicate_request(stl, 8, 9, settings) == first
    assert K.replicate_request(stl, 16, 9, settings) != first
    stl.write_bytes(open(f"{PARTS_DIR}/hex-a.stl", "rb").read())
    assert K.replicate_request(stl, 8, 9, settings) != first  # another part under the same name
    assert json.loads(first)["code"] == K.source_digest("feeder.sim.simulate")
    assert K.source_digest("feeder.sim.simulate") != K.source_digest("feeder.learn.structured_protocol")


def test_a_replicate_is_simulated_once_and_read_back(tmp_path, monkeypatch):
    settings = _settings()
    settings["sim"]["preset"] = "coarse"
    path = tmp_path / "sim" / "rect-a3" / "straight30_none__b4.npz"
    first = K.replicate_label(f"{PARTS_DIR}/rect-a3.stl", "straight30_none", 4, 5, settings, 0.0, path)
    assert path.is_file() and first[2] == 4 and first[1] > 0
    assert first[0] is not None and first[0].sum() == pytest.approx(1.0)
    import feeder.sim.simulate as S

    def no_simulation(*args, **kwargs):
        raise AssertionError("simulated again")

    monkeypatch.setattr(S, "simulate", no_simulation)
    again = K.replicate_label(f"{PARTS_DIR}/rect-a3.stl", "straight30_none", 4, 5, settings, 0.0, path)
    assert np.array_equal(again[0], first[0]) and again[1:] == first[1:]
    with pytest.raises(AssertionError, match="simulated again"):  # another seed is another request
        K.replicate_label(f"{PARTS_DIR}/rect-a3.stl", "straight30_none", 4, 6, settings, 0.0, path)
    # the label frame: turned by the part's frame, as the study's labels are
    assert settings["labels"]["frame"] == "principal"
    turned = K.replicate_label(f"{PARTS_DIR}/rect-a3.stl", "straight30_none", 4, 5, settings, 30.0, path)[0]
    assert K.scores(turned, np.roll(first[0], 30))["circular_w1_deg"] < 0.5
    assert K.scores(turned, first[0])["circular_w1_deg"] > 5.0


def test_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "t.csv"
    base = ["bench-frontier-known", "--dataset", str(tmp_path / "none.npz"), "--sim-dir", str(tmp_path)]
    base += ["--parts-dir", PARTS_DIR, "--features-dir", str(tmp_path), "--work-dir", str(tmp_path / "w")]
    base += ["--out-raw", str(tmp_path / "r.csv"), "--out-csv", str(out)]
    assert cli([*base, "--settings", json.dumps(_settings(budgets=[1]))]) != 0
    assert "at least 2 drops" in capsys.readouterr().err
    assert cli([*base, "--settings", json.dumps(_settings())]) != 0
    assert "is missing" in capsys.readouterr().err
    assert not out.exists() and not (tmp_path / "r.csv").exists() and not (tmp_path / "w").exists()


def test_the_fit_key_follows_the_training_rows_inputs_and_settings():
    from feeder.config import compose_config

    cfg = compose_config("structured", [])
    rng = np.random.default_rng(0)
    arrays = {
        "part": np.array(["a", "a", "b"]),
        "config_id": np.array(["x", "y", "x"]),
        "x": rng.random((3, 4)),
        "analytic": rng.random((3, 6)),
        "ok": np.ones(3),
        "frame_deg": np.zeros(3),
        "pmf": rng.random((3, 6)),
        "kept": np.ones(3, dtype=bool),
    }
    data = {"settings": json.dumps({"labels": {"bins": 6}}), "label_frame": "principal"}
    train = np.array([True, True, False])
    key = K.fit_key(arrays, train, cfg, data)
    assert K.fit_key(arrays, train, cfg, data) == key
    other = dict(arrays, x=arrays["x"].copy())
    other["x"][2] += 1.0  # a row outside the fit: the same key
    assert K.fit_key(other, train, cfg, data) == key
    other["x"][0] += 1.0  # an input of a training row
    assert K.fit_key(other, train, cfg, data) != key
    assert K.fit_key(arrays, np.array([True, False, False]), cfg, data) != key
    assert K.fit_key(arrays, train, compose_config("structured", ["seeds=1"]), data) != key
    assert K.fit_key(arrays, train, cfg, dict(data, label_frame="part")) != key
