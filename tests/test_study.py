"""The study's answer (feeder.learn.study): labels where the study simulated the part, the analytic PMF elsewhere."""

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

from feeder.errors import FeederError
from feeder.labels import metrics as L
from feeder.learn import study as S
from feeder.learn.export import MODEL_DIR_ENV
from feeder.mechanics.features import PUSH_FEATURE_NAMES

ROOT = Path(__file__).resolve().parents[1]
SCENE = {"belt": {"speed": 0.1, "friction": 1.0}, "part": {"friction": 0.8}}
RANDOM = json.dumps({"yaw_sampling": "random"})


# ---------------------------------------------------------------------------------- pure functions
def test_the_nearest_configuration_is_of_the_same_fence_types_by_angle_distance():
    pool = ["straight30_none", "straight50_none", "curved40_none", "straight40_curved20", "straight20_none"]
    assert S.nearest_configuration("straight35_none", pool) == (0, 5.0)
    assert S.nearest_configuration("straight40_none", pool) == (0, 10.0)  # 30 and 50 both 10 away: the earlier
    assert S.nearest_configuration("straight15_none", pool) == (4, 5.0)
    assert S.nearest_configuration("curved10_none", pool) == (2, 30.0)
    assert S.nearest_configuration("straight45_curved10", pool) == (3, 15.0)  # |5| + |10|
    assert S.nearest_configuration("none_straight30", pool) == (-1, math.inf)  # no pool row has these types
    assert S.nearest_configuration("straight30_none", []) == (-1, math.inf)


def test_digests_tell_files_and_scenes_apart(tmp_path):
    a, b = tmp_path / "a.stl", tmp_path / "b.stl"
    a.write_bytes(b"solid a")
    b.write_bytes(b"solid b")
    assert S.file_digest(a) != S.file_digest(b) and S.file_digest(a) == S.file_digest(a)
    assert S.file_digest(a) == hashlib.sha256(b"solid a").hexdigest()
    reordered = {"part": {"friction": 0.8}, "belt": {"friction": 1.0, "speed": 0.1}}
    assert S.scene_digest(SCENE) == S.scene_digest(reordered)
    assert S.scene_digest(SCENE) != S.scene_digest({**SCENE, "part": {"friction": 0.81}})


def test_ragged_rows_are_padded():
    out = S.pad_rows([np.array([1.0, 2.0]), np.array([3.0])], np.nan, np.float64)
    assert out.shape == (2, 2) and out[0].tolist() == [1.0, 2.0] and out[1, 0] == 3.0 and np.isnan(out[1, 1])
    assert S.pad_rows([], 0, np.int64).shape == (0, 0)


@pytest.mark.parametrize("gates", [[], [-1.0], [float("nan")], ["x"], None])
def test_bad_gates_are_refused(gates):
    with pytest.raises(FeederError, match="neighbour.gates_deg"):
        S.check_gates(gates)


# ----------------------------------------------------------------------------- a small library
def _library(part_stl: Path, gate: float = 20.0) -> S.Library:
    rows = [  # part, config, final yaws (NaN: not ok), statuses, kept
        ("p", "straight30_none", [10.0, 10.0, 190.0, 190.0], ["ok"] * 4, True),
        ("p", "straight60_none", [100.0] * 4, ["ok"] * 4, True),
        ("p", "curved40_none", [np.nan] * 4, ["jammed"] * 4, False),
        ("q", "straight30_none", [45.0] * 4, ["ok"] * 4, True),
    ]
    return S.Library(
        part=np.array([r[0] for r in rows]),
        config_id=np.array([r[1] for r in rows]),
        kept=np.array([r[4] for r in rows]),
        final_yaw_deg=np.array([r[2] for r in rows]),
        initial_yaw_deg=np.tile(np.arange(4) * 90.0, (len(rows), 1)),
        status=np.array([r[3] for r in rows]),
        drops=np.full(len(rows), 4),
        meta=np.array([RANDOM] * len(rows)),
        part_ids=np.array(["p", "q"]),
        part_digests=np.array([S.file_digest(part_stl), "0" * 64]),
        card={"format": S.LIBRARY_FORMAT, "gate_deg": gate, "scene_sha256": S.scene_digest(SCENE)},
    )


@pytest.fixture
def part_stl(tmp_path) -> Path:
    path = tmp_path / "p.stl"
    path.write_bytes(b"solid p\nendsolid p\n")
    return path


def _push(ok: float, rows: int) -> np.ndarray:
    push = np.zeros((rows, len(PUSH_FEATURE_NAMES)))
    push[:, PUSH_FEATURE_NAMES.index("ok_mass")] = ok
    return push


def test_each_configuration_gets_the_answer_the_tables_support(part_stl):
    model = S.StudyModel(360, 1.0, SCENE, _library(part_stl))
    ids = ["straight30_none", "straight45_none", "straight40_none", "curved40_none", "curved10_none", "none_none"]
    assert model.bind(part_stl, ids) == "part p of the study (3 simulated configurations)"
    # 45: 30 and 60 both 15 away (the earlier); curved10: the only curved row jams, so it is no neighbour
    assert model.sources() == ["simulated", "neighbour", "neighbour", "simulated", "analytic", "analytic"]
    assert [a[1] for a in model.answers] == [0, 0, 0, 2, -1, -1]
    assert "straight30_none (15 deg away, gate 20)" in model.describe(1)
    uniform = np.full((len(ids), 360), 1.0)
    pmf, cdf = model.predict(np.zeros((len(ids), 45)), np.zeros((len(ids), 8)), _push(0.5, len(ids)), uniform)
    want = L.pmf_from_yaws(np.array([10.0, 10.0, 190.0, 190.0]), 360, 1.0)
    for r in (0, 1, 2):
        assert np.allclose(pmf[r], want, atol=1e-15)
    assert not pmf[3].any()  # every drop jammed: no orientation, ok mass 0
    assert np.allclose(pmf[4:], 1.0 / 360) and np.allclose(cdf, np.cumsum(pmf, axis=1))
    assert model.ok_mass(_push(0.5, len(ids))).tolist() == [1.0, 1.0, 1.0, 0.0, 0.5, 0.5]


def test_a_gate_of_zero_answers_only_what_was_simulated(part_stl):
    model = S.StudyModel(360, 1.0, SCENE, _library(part_stl, gate=0.0))
    model.bind(part_stl, ["straight30_none", "straight31_none"])
    assert model.sources() == ["simulated", "analytic"]
    assert "1 deg away, gate 0" in model.describe(1)


def test_a_new_part_or_another_scene_gets_the_analytic_pmf(part_stl, tmp_path):
    other = tmp_path / "other.stl"
    other.write_bytes(b"solid p\nendsolid p \n")  # one byte more: another file
    model = S.StudyModel(360, 1.0, SCENE, _library(part_stl))
    assert "not simulated" in model.bind(other, ["straight30_none"])
    assert model.sources() == ["analytic"]
    elsewhere = S.StudyModel(360, 1.0, {**SCENE, "belt": {"speed": 0.2, "friction": 1.0}}, _library(part_stl))
    assert "another scene" in elsewhere.bind(part_stl, ["straight30_none"])
    assert elsewhere.sources() == ["analytic"]
    pmf, _ = elsewhere.predict(np.zeros((1, 45)), np.zeros((1, 8)), _push(1.0, 1), np.arange(360.0)[None] + 1)
    assert np.allclose(pmf[0], (np.arange(360.0) + 1) / np.sum(np.arange(360.0) + 1))


def test_the_predictor_must_be_bound_first(part_stl):
    model = S.StudyModel(360, 1.0, SCENE, _library(part_stl))
    with pytest.raises(FeederError, match="bind"):
        model.predict(np.zeros((1, 45)), np.zeros((1, 8)), _push(1.0, 1), np.ones((1, 360)))
    model.bind(part_stl, ["straight30_none"])
    with pytest.raises(FeederError, match="bound to 1"):
        model.predict(np.zeros((2, 45)), np.zeros((2, 8)), _push(1.0, 2), np.ones((2, 360)))


class _Shipped:
    """A stand-in for the shipped structured predictor (its neighbour rule is the real one): it
    answers a spike at 50 deg in the label frame, turned 10 deg from the part's, and keeps its calls."""

    frame = 10.0

    def __init__(self):
        from feeder.learn.structured_shipped import ShippedStructured

        self.rule = ShippedStructured.__new__(ShippedStructured)
        self.rule.meta = {"neighbours": 2, "cross_neighbours": 1}
        self.calls = []
        self.networks = {"default": None}

    def serves(self, bins, sigma_bins, scene_sha256):
        return scene_sha256 == S.scene_digest(SCENE)

    def has_neighbour(self, config_id, pool_ids):
        return self.rule.has_neighbour(config_id, pool_ids)

    def mirrored_ids(self, part, pool_ids):
        self.rule.mirrors = getattr(self, "mirrors", {})
        return self.rule.mirrored_ids(part, pool_ids)

    def frame_of(self, part):
        return self.frame

    units = "auto"

    def knows(self, part):
        return part == "p"

    composes = False

    def answer(self, geom, part, config_ids, pool_ids, pool_pmf, pool_ok, scene, progress=None, pool_maps=None):
        self.calls.append((part, list(config_ids), list(pool_ids), np.asarray(pool_pmf), list(pool_ok)))
        self.maps = pool_maps
        out = np.zeros((len(config_ids), 360))
        out[:, 50] = 1.0
        return out


def test_a_known_part_at_a_new_angle_gets_the_structured_predictor_where_it_has_a_neighbour(tmp_path):
    stl = tmp_path / "p.stl"
    stl.write_bytes((Path(__file__).resolve().parents[1] / "parts" / "rect-a3.stl").read_bytes())
    lib = _library(stl)
    lib.structured = _Shipped()
    model = S.StudyModel(360, 1.0, SCENE, lib)
    ids = ["straight30_none", "straight45_none", "straight20_curved30", "curved10_none", "none_none"]
    model.bind(stl, ids)
    # curved10: the part's only curved row jams, and no labelled row has a curved downstream fence
    assert model.sources() == ["simulated", "structured", "structured", "analytic", "analytic"]
    assert "straight30_none, 15 deg away" in model.describe(1) and "only of its downstream fence" in model.describe(2)
    assert "Fences specialist" not in model.describe(2)
    lib.structured.networks["specialist"] = None  # shipped with one: it answers row 2, and says so
    assert "its Fences specialist answers" in model.describe(2) and "specialist" not in model.describe(1)
    uniform = np.full((len(ids), 360), 1.0 / 360)
    pmf, _ = model.predict(np.zeros((5, 45)), np.zeros((5, 8)), _push(0.5, 5), uniform)
    assert pmf[1, 40] == pytest.approx(1.0) and pmf[2, 40] == pytest.approx(1.0)  # 50 in the label frame
    (call,) = lib.structured.calls  # one answer for every structured row of the binding
    part, asked, pool, pool_pmf, pool_ok = call
    assert part == "p" and asked == ids[1:3] and pool == ["straight30_none", "straight60_none"]
    assert np.allclose(pool_pmf[0], L.pmf_from_yaws(np.array([20.0, 20.0, 200.0, 200.0]), 360, 1.0))  # label frame
    assert pool_ok == [1.0, 1.0]
    assert model.ok_mass(_push(0.5, 5)).tolist() == [1.0, 0.5, 0.5, 0.5, 0.5]  # the analytic ok mass
    elsewhere = S.StudyModel(360, 1.0, {**SCENE, "belt": {"speed": 0.2, "friction": 1.0}}, lib)
    assert elsewhere.structured is None
    lib.structured.knows = lambda part: False  # a library part the shipped file was not trained with
    model = S.StudyModel(360, 1.0, SCENE, lib)
    model.bind(stl, ids)
    assert model.sources() == ["simulated", "neighbour", "analytic", "analytic", "analytic"]


def test_a_mirror_predictor_answers_a_query_at_the_other_location_and_says_whose_label_it_read(tmp_path):
    """model.mirror_labels: a Location 2 query of a part with labels only at Location 1 has a
    neighbour (straight30_none read at Location 2, 5 deg away) and the structured predictor answers;
    without the part's mirror constant it has none, and the analytic PMF answers."""
    stl = tmp_path / "p.stl"
    stl.write_bytes((Path(__file__).resolve().parents[1] / "parts" / "rect-a3.stl").read_bytes())
    lib = _library(stl)
    lib.structured = _Shipped()
    lib.structured.rule.meta["cross_neighbours"] = 0
    model = S.StudyModel(360, 1.0, SCENE, lib)
    model.bind(stl, ["none_straight35"])
    assert model.sources() == ["analytic"]
    lib.structured.mirrors = {"p": 90.0}
    model.bind(stl, ["none_straight35"])
    assert model.sources() == ["structured"]
    assert "straight30_none read at the other location (the part's mirror image), 5 deg away" in model.describe(0)
    model.predict(np.zeros((1, 45)), np.zeros((1, 8)), _push(0.5, 1), np.full((1, 360), 1.0 / 360))
    assert lib.structured.calls[0][2] == ["straight30_none", "straight60_none"]  # the labels as they are


def test_a_composing_predictor_gets_the_parts_one_fence_drop_maps(tmp_path):
    stl = tmp_path / "p.stl"
    stl.write_bytes((Path(__file__).resolve().parents[1] / "parts" / "rect-a3.stl").read_bytes())
    lib = _library(stl)
    grid = json.dumps({"yaw_sampling": "grid", "design": "grid"})
    lib.meta = np.array([grid, RANDOM, grid, grid])  # straight60_none: random drops sample no map
    lib.config_id[1] = "none_straight60"
    lib.structured = _Shipped()
    lib.structured.composes = True
    lib.structured.rule.meta["composed"] = True
    model = S.StudyModel(360, 1.0, SCENE, lib)
    model.bind(stl, ["straight20_straight50"])
    assert model.sources() == ["structured"]
    model.predict(np.zeros((1, 45)), np.zeros((1, 8)), _push(0.5, 1), np.full((1, 360), 1.0 / 360))
    assert lib.structured.calls[0][2] == ["straight30_none", "none_straight60"]
    assert list(lib.structured.maps) == [0]  # the random-drop row has no map; the jammed row is no pool row
    assert lib.structured.maps[0].final.tolist() == [10.0, 10.0, 190.0, 190.0]


def test_a_broken_structured_file_is_a_one_line_error(tmp_path):
    parts_dir, sim_dir = _study_inputs(tmp_path)
    out = tmp_path / "study"
    _export(tmp_path, sim_dir, parts_dir, [0], out)
    assert S.load_library(out).structured is None  # exported without one: the nearest labels answer
    (out / "structured.npz").write_bytes(b"not a zip")
    with pytest.raises(FeederError, match="not a structured predictor's file"):
        S.load_library(out)


# ------------------------------------------------------------------------------- export and load
def _study_inputs(tmp_path: Path):
    from feeder.io import write_npz

    parts_dir, sim_dir = tmp_path / "parts", tmp_path / "sim"
    parts_dir.mkdir()
    (parts_dir / "p.stl").write_bytes(b"solid p\n")
    ids = ["straight30_none", "straight40_none", "straight80_none", "curved40_none"]
    yaws = {"straight30_none": 10.0, "straight40_none": 12.0, "straight80_none": 200.0, "curved40_none": 90.0}
    for cid, yaw in yaws.items():
        status = np.array(["ok", "ok", "jammed"] if cid != "curved40_none" else ["jammed"] * 3)
        final = np.where(status == "ok", yaw, np.nan)
        write_npz(
            sim_dir / "p" / f"{cid}.npz",
            final_yaw_deg=final,
            initial_yaw_deg=np.array([0.0, 120.0, 240.0]),
            status=status,
            wall_s=np.float64(1.0),
            cpu_s=np.float64(1.0),
            meta=np.array(RANDOM),
        )
    labelled = ids[:3]
    pmf = np.stack([L.pmf_from_yaws(np.array([yaws[c]]), 360, 1.0) for c in labelled])
    analytic = np.stack([L.pmf_from_yaws(np.array([yaws[c] + 40.0]), 360, 1.0) for c in labelled])
    write_npz(
        tmp_path / "dataset.npz",
        part=np.array(["p"] * 3),
        config_id=np.array(labelled),
        pmf=pmf,
        pmf_analytic=analytic,
        settings=np.array(json.dumps({"scene": SCENE, "sim": {"drops": 3}})),
    )
    pd.DataFrame({"part": ["p"] * 4, "config_id": ids}).to_csv(tmp_path / "configurations.csv", index=False)
    cols = ["predictor", "baseline", "metric", "configurations", "repeats", "value", "baseline_value", "diff"]
    cols += ["diff_low", "diff_high", "level", "verdict"]
    row = ["neighbour_gated", "analytic_pmf", "cw1", 10, 3, 5.0, 8.0, -3.0, -4.0, -2.0, 0.95, "better"]
    pd.DataFrame([row], columns=cols).to_csv(tmp_path / "neighbour.csv", index=False)
    return parts_dir, sim_dir


def _export(tmp_path: Path, sim_dir: Path, parts_dir: Path, gates, out: Path) -> dict:
    """:func:`S.export_study` of the inputs of :func:`_study_inputs` into ``out``."""
    return S.export_study(
        pd.read_csv(tmp_path / "configurations.csv"),
        sim_dir,
        parts_dir,
        tmp_path / "dataset.npz",
        tmp_path / "neighbour.csv",
        gates,
        out,
    )


def test_export_writes_a_library_that_loads_back(tmp_path):
    parts_dir, sim_dir = _study_inputs(tmp_path)
    out = tmp_path / "models" / "study"
    card = _export(tmp_path, sim_dir, parts_dir, [0, 5, 20, 180], out)
    # each labelled row from its nearest other: 30 <- 40 (10 deg, W1 2), 40 <- 30 (2), 80 <- 40 (40 deg, 172
    # around the circle); the analytic PMF is 40 deg off everywhere. Gate 20 takes the first two only.
    scores = pd.DataFrame(card["gate_scores"]).set_index("gate_deg").circular_w1_deg
    assert scores[0.0] == pytest.approx(40.0, abs=0.01) and scores[5.0] == pytest.approx(40.0, abs=0.01)
    assert scores[20.0] == pytest.approx((2 + 2 + 40) / 3, abs=0.01)
    assert scores[180.0] == pytest.approx((2 + 2 + 172) / 3, abs=0.01)
    assert card["gate_deg"] == 20.0 and card["configurations"] == 4 and card["labelled"] == 3 and card["parts"] == 1
    assert card["scene_sha256"] == S.scene_digest(SCENE) and card["test_evidence"]["diff"] == -3.0
    lib = S.load_library(out)
    assert lib.kept.tolist() == [True, True, True, False] and lib.drops.tolist() == [3, 3, 3, 3]
    rec = lib.record(1)
    assert rec.ok.tolist() == [True, True, False] and np.allclose(rec.yaws[:2], 12.0)
    assert (out / "MODEL_CARD.md").read_text().count("|") > 10
    (tmp_path / "plain").mkdir()
    (tmp_path / "plain" / "notes.txt").write_text("mine")
    with pytest.raises(FeederError, match="not an exported study folder"):
        _export(tmp_path, sim_dir, parts_dir, [0], tmp_path / "plain")
    assert (tmp_path / "plain" / "notes.txt").read_text() == "mine"


def test_each_label_carries_its_audit_estimate_into_the_answer(tmp_path, part_stl):
    parts_dir, sim_dir = _study_inputs(tmp_path)
    ids = ["straight30_none", "straight40_none", "straight80_none", "curved40_none"]
    table = pd.DataFrame(
        {"part": ["p"] * 4, "config_id": ids, "est_circular_w1_deg": [2.5, 3.0, 40.0, np.nan]}
        | {"est_sup_cdf": [0.03, 0.04, 0.5, np.nan]}
    )
    table.iloc[::-1].to_csv(tmp_path / "errors.csv", index=False)  # matched by id, not by order
    out = tmp_path / "study"
    args = (pd.read_csv(tmp_path / "configurations.csv"), sim_dir, parts_dir, tmp_path / "dataset.npz")
    card = S.export_study(*args, tmp_path / "neighbour.csv", [0, 20], out, label_errors=tmp_path / "errors.csv")
    assert card["label_errors"] == {"audited": 3, "est_circular_w1_deg_median": 3.0}  # the kept labels
    lib = S.load_library(out)
    np.testing.assert_array_equal(lib.est_circular_w1_deg, [2.5, 3.0, 40.0, np.nan])
    assert "median circular W1 3.0 deg" in (out / "MODEL_CARD.md").read_text()
    model = S.StudyModel(360, 1.0, SCENE, lib)
    model.library.part_digests = np.array([S.file_digest(part_stl)])
    model.bind(part_stl, ["straight40_none", "curved40_none"])
    assert model.describe(0).endswith(
        "within circular W1 3.0 deg and sup|dCDF| 0.040 of the simulator's exact label (upper estimates, feeder audit)"
    )
    assert model.describe(1) == "the study's simulated label of curved40_none"  # no label, no estimate
    np.testing.assert_array_equal(model.label_error_deg(), [3.0, np.nan])  # recommend's column
    model.bind(part_stl, ["straight30_none", "straight45_none"])  # a label, then no label: another answer
    assert model.sources()[1] != "simulated"
    np.testing.assert_array_equal(model.label_error_deg(), [2.5, np.nan])
    # an export without the table: the answer says nothing of an estimate
    S.export_study(*args, tmp_path / "neighbour.csv", [0, 20], tmp_path / "plain")
    plain = S.load_library(tmp_path / "plain")
    assert plain.est_circular_w1_deg is None and "label_errors" not in plain.card
    bare = S.StudyModel(360, 1.0, SCENE, plain)
    bare.library.part_digests = np.array([S.file_digest(part_stl)])
    bare.bind(part_stl, ["straight40_none"])
    assert bare.sources() == ["simulated"] and np.isnan(bare.label_error_deg()).all()
    table.iloc[1:].to_csv(tmp_path / "short.csv", index=False)
    with pytest.raises(FeederError, match="no row for p straight30_none"):
        S.export_study(*args, tmp_path / "neighbour.csv", [0, 20], tmp_path / "x", label_errors=tmp_path / "short.csv")


@pytest.mark.parametrize(
    ("config_id", "kind"),
    [
        ("straight30_none", "straight_none"),
        ("straight50_none", "straight_none, steep"),  # at the threshold: steep
        ("none_straight49.9", "none_straight"),
        ("curved80_none", "curved_none"),  # a curved fence is never "steep": its own kind
        ("curved20_straight55", "curved_straight, steep"),
        ("straight60_straight15", "straight_straight, steep"),  # either straight fence
        ("none_none", "none_none"),
    ],
)
def test_scene_kinds_by_hand(config_id, kind):
    assert S.scene_kind(config_id, 50.0) == kind


@pytest.mark.parametrize("bad", [0, -5, 90, 120, "steep", None, float("nan")])
def test_a_bad_steep_angle_is_refused(bad):
    with pytest.raises(FeederError, match="analytic_scenes.steep_deg"):
        S.check_steep_deg(bad)


def test_the_analytic_error_by_scene_by_hand():
    """Labels at 10, 20 and 30 deg; analytic PMFs 40, 30 and 0 deg off (30's is a half-and-half mix
    of 10 and 50 deg: W1 20 to a label at 30). Two straight scenes below 50, one steep."""

    def at(*yaws):
        return L.pmf_from_yaws(np.array(yaws, dtype=float), 360, 0.0)

    ids = ["straight30_none", "straight40_none", "straight55_none"]
    pmf = np.stack([at(10.0), at(20.0), at(30.0)])
    analytic = np.stack([at(50.0), at(350.0), at(10.0, 50.0)])
    rows = {r["scene"]: r for r in S.analytic_by_scene(ids, pmf, analytic, 50.0)}
    assert list(rows) == ["straight_none", "straight_none, steep"]
    low, steep = rows["straight_none"], rows["straight_none, steep"]
    assert low["configurations"] == 2 and steep["configurations"] == 1
    assert low["mean_circular_w1_deg"] == pytest.approx(35.0) and low["median_circular_w1_deg"] == pytest.approx(35.0)
    assert low["p90_circular_w1_deg"] == pytest.approx(30.0 + 0.9 * 10.0)  # numpy's linear percentile of 30, 40
    assert steep["mean_circular_w1_deg"] == pytest.approx(20.0)
    with pytest.raises(FeederError, match="one label and one analytic PMF"):
        S.analytic_by_scene(ids[:2], pmf, analytic, 50.0)


def test_an_analytic_answer_says_how_far_the_analytic_pmf_lay_in_scenes_of_its_kind(tmp_path, part_stl):
    parts_dir, sim_dir = _study_inputs(tmp_path)
    args = (pd.read_csv(tmp_path / "configurations.csv"), sim_dir, parts_dir, tmp_path / "dataset.npz")
    card = S.export_study(*args, tmp_path / "neighbour.csv", [0, 20], tmp_path / "study", steep_deg=50.0)
    # the dataset's labels: straight 30, 40 and 80, each 40 deg from its analytic PMF
    kinds = {k["scene"]: k for k in card["analytic_scenes"]["kinds"]}
    assert card["analytic_scenes"]["steep_deg"] == 50.0
    assert kinds["straight_none"]["configurations"] == 2 and kinds["straight_none, steep"]["configurations"] == 1
    assert kinds["straight_none"]["mean_circular_w1_deg"] == pytest.approx(40.0, abs=0.01)
    assert "| straight_none, steep | 1 | 40.0 | 40.0 | 40.0 |" in (tmp_path / "study" / "MODEL_CARD.md").read_text()
    other = tmp_path / "other.stl"
    other.write_bytes(b"solid other\n")
    model = S.StudyModel(360, 1.0, SCENE, S.load_library(tmp_path / "study"))
    model.bind(other, ["straight35_none", "straight70_none", "curved40_none"])
    assert model.describe(0) == (
        "the analytic push PMF; on the study's 2 labelled configurations of this kind (straight_none) it lay "
        "circular W1 40.0 deg from the simulator on average (median 40.0, 90th percentile 40.0); "
        "--simulate BUDGET asks the simulator"
    )
    assert "(straight_none, steep)" in model.describe(1)
    assert model.describe(2) == "the analytic push PMF"  # no labelled scene of its kind: nothing to say
    np.testing.assert_allclose(model.analytic_error_deg(), [40.0, 40.0, np.nan], atol=0.01)  # recommend's column
    elsewhere = S.StudyModel(360, 1.0, {**SCENE, "belt": {"speed": 0.2, "friction": 1.0}}, model.library)
    elsewhere.bind(other, ["straight35_none"])
    assert elsewhere.describe(0) == "the analytic push PMF"  # measured in another scene: not quoted
    plain = S.export_study(*args, tmp_path / "neighbour.csv", [0, 20], tmp_path / "plain")
    assert "analytic_scenes" not in plain  # an export without the setting (an older card) says nothing either


def test_a_missing_or_foreign_library_is_a_one_line_error(tmp_path):
    with pytest.raises(FeederError, match="make run"):
        S.load_library(tmp_path / "nowhere")
    folder = tmp_path / "study"
    folder.mkdir()
    (folder / S.LABELS_FILE).write_bytes(b"")
    for text, message in [("{", "not JSON"), ('{"format": 99}', "format 99"), ("[]", "format None")]:
        (folder / S.CARD_FILE).write_text(text)
        with pytest.raises(FeederError, match=message):
            S.load_library(folder)


# ------------------------------------------------------------------- the committed library, by CLI
def _cli(*args: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != MODEL_DIR_ENV}
    return subprocess.run([sys.executable, "-m", "feeder", *args], capture_output=True, text=True, env=env, timeout=300)


def test_the_committed_library_is_of_the_default_scene():
    from feeder.config import load_study_config

    lib = S.load_library(ROOT / "models" / "study")
    assert lib.card["scene_sha256"] == S.scene_digest(load_study_config(root=ROOT)["scene"])
    for pid, digest in zip(lib.part_ids, lib.part_digests, strict=True):
        assert S.file_digest(ROOT / "parts" / f"{pid}.stl") == digest, pid


def test_predict_answers_a_simulated_configuration_with_its_label():
    from feeder.labels.pmf import sim_label
    from feeder.lane.fences import parse_config_id

    lib = S.load_library(ROOT / "models" / "study")
    i = int(np.flatnonzero(lib.kept)[0])
    part, cid = str(lib.part[i]), str(lib.config_id[i])
    loc1, loc2 = parse_config_id(cid)
    proc = _cli("predict", "--part", str(ROOT / "parts" / f"{part}.stl"), "--loc1", loc1.spec, "--loc2", loc2.spec)
    assert proc.returncode == 0, proc.stderr
    assert f"the study's simulated label of {cid}" in proc.stderr
    got = pd.read_csv(io.StringIO(proc.stdout))
    want = sim_label(lib.record(i), 360, 1.0).pmf
    assert np.allclose(got.pmf, want, atol=1e-9)


def test_predict_gives_a_new_part_the_analytic_pmf(tmp_path):
    from feeder.parts.geometry import stl_bytes

    part = tmp_path / "my-bracket.stl"
    part.write_bytes(stl_bytes(np.array([(0.0, 0.0), (31.0, -4.0), (47.0, 9.0), (38.0, 26.0), (-6.0, 14.0)]), 7.0, "b"))
    base = ["predict", "--part", str(part), "--loc1", "straight:30", "--loc2", "none"]
    study = _cli(*base, "--out", str(tmp_path / "s.csv"))
    analytic = _cli(*base, "--model", "analytic", "--out", str(tmp_path / "a.csv"))
    assert study.returncode == 0 and analytic.returncode == 0, study.stderr + analytic.stderr
    assert "a part the study has not simulated" in study.stderr
    assert pd.read_csv(tmp_path / "s.csv").equals(pd.read_csv(tmp_path / "a.csv"))


def test_export_study_refuses_bad_input_in_one_line_and_writes_nothing(tmp_path):
    parts_dir, sim_dir = _study_inputs(tmp_path)
    (tmp_path / "bad.csv").write_text("part,config\np,straight30_none\n")
    out = tmp_path / "models" / "study"
    base = ["export-study", "--sim-dir", str(sim_dir), "--parts-dir", str(parts_dir), "--out", str(out)]
    base += ["--dataset", str(tmp_path / "dataset.npz"), "--neighbour-table", str(tmp_path / "neighbour.csv")]
    for configurations, gates, message in [
        (tmp_path / "missing.csv", [], "missing.csv is missing"),
        (tmp_path / "bad.csv", [], "no column config_id"),
        (tmp_path / "configurations.csv", ["neighbour.gates_deg=[]"], "neighbour.gates_deg"),
        (tmp_path / "configurations.csv", ["analytic_scenes.steep_deg=0"], "analytic_scenes.steep_deg"),
        (tmp_path / "configurations.csv", ["analytic_scenes.steep_deg=steep"], "analytic_scenes.steep_deg"),
    ]:
        proc = _cli(*base, "--configurations", str(configurations), *gates)
        err = proc.stderr.strip()
        assert proc.returncode != 0 and message in err and "\n" not in err and "Traceback" not in err, err
        assert not out.exists()
    good = ["--configurations", str(tmp_path / "configurations.csv")]
    for extra, message in [
        (["--structured-table", str(tmp_path / "neighbour.csv")], "--structured-table is the evidence of --structured"),
        (
            ["--structured-errors", str(tmp_path / "neighbour.csv")],
            "--structured-errors is the evidence of --structured",
        ),
        (["--structured", str(tmp_path / "none.npz")], "none.npz is missing"),
    ]:
        proc = _cli(*base, *good, *extra)
        err = proc.stderr.strip()
        assert proc.returncode != 0 and message in err and "\n" not in err and "Traceback" not in err, err
        assert not out.exists()
    (sim_dir / "p" / "straight40_none.npz").write_bytes(b"not a zip")
    proc = _cli(*base, "--configurations", str(tmp_path / "configurations.csv"))
    err = proc.stderr.strip()
    assert proc.returncode != 0 and "straight40_none.npz" in err and "\n" not in err and not out.exists()


def test_the_card_quotes_one_model_of_the_structured_table():
    from feeder.learn.study import EVIDENCE_MODEL, structured_evidence

    def row(model, experiment, baseline, value):
        return {
            "experiment": experiment,
            "unit": "configuration",
            "model": model,
            "metric": "cw1",
            "baseline": baseline,
            "n": 5,
            "structured": value,
            "structured_seed_sd": np.nan,
            "baseline_value": 9.0,
            "diff": value - 9.0,
            "diff_low": value - 10.0,
            "diff_high": value - 8.5,
            "level": 0.95,
            "verdict": "better",
        }

    rows = [
        row(m, e, "analytic_pmf", v)
        for m, v in (("structured", 7.0), ("structured_ensemble", 6.5))
        for e in ("test", "fences")
    ]
    quoted = structured_evidence(pd.DataFrame(rows + [row("structured", "unseen_groupkfold", "analytic_pmf", 1.0)]))
    assert [(q["experiment"], q["structured"]) for q in quoted] == [
        ("test", 7.0 if EVIDENCE_MODEL == "structured" else 6.5),
        ("fences", 7.0 if EVIDENCE_MODEL == "structured" else 6.5),
    ]
    old = pd.DataFrame(rows[:2]).drop(columns="model")  # a table written before the model column
    assert [q["structured"] for q in structured_evidence(old)] == [7.0, 7.0]


def test_a_structured_answer_says_how_far_it_may_be_off_at_its_distance(tmp_path):
    """The card's error bins by neighbour distance (structured_by_distance.csv): the answer quotes
    the bin of its nearest label of the same fence types, or the bin of none where it reads only a
    label of its downstream fence type; a card without them says nothing."""
    table = pd.DataFrame(
        {
            "low_deg": [0.0, 10.0, 20.0, np.inf],
            "high_deg": [10.0, 20.0, 180.0, np.inf],
            "model": "structured_ensemble",
            "rows": [4, 0, 7, 9],
            "mean_circular_w1_deg": [2.5, np.nan, 12.0, 14.0],
            "median_circular_w1_deg": [1.5, np.nan, 7.0, 10.0],
            "p90_circular_w1_deg": [6.0, np.nan, 30.0, 31.0],
        }
    )
    bins = S.structured_error_bins(table)
    assert [b["rows"] for b in bins] == [4, 7, 9]  # the empty bin is left out
    assert bins[-1]["low_deg"] is None and json.loads(json.dumps(bins, allow_nan=False)) == bins  # JSON-safe
    assert S.error_bin(bins, 0.0)["rows"] == 4 and S.error_bin(bins, 9.99)["rows"] == 4
    assert S.error_bin(bins, 15.0) is None and S.error_bin(bins, 20.0)["rows"] == 7
    assert S.error_bin(bins, 180.0)["rows"] == 7  # the last bin is closed: 180 is the most a 0-90 grid has
    assert S.error_bin(bins, 180.5) is None and S.error_bin(bins, float("inf"))["rows"] == 9
    assert S.distance_words(bins[0]) == "0 to 10 deg away" and S.distance_words(bins[2]) == "none of its fence types"
    with pytest.raises(FeederError, match="no column rows"):
        S.structured_error_bins(table.drop(columns="rows"))

    stl = tmp_path / "p.stl"
    stl.write_bytes((Path(__file__).resolve().parents[1] / "parts" / "rect-a3.stl").read_bytes())
    lib = _library(stl)
    lib.structured = _Shipped()
    lib.card = {**lib.card, "structured": {"by_distance": bins}}
    model = S.StudyModel(360, 1.0, SCENE, lib)
    model.bind(stl, ["straight85_none", "straight20_curved30", "straight35_none", "straight45_none"])
    assert model.sources()[:3] == ["structured"] * 3
    assert model.describe(0).endswith(  # 25 deg from straight60
        "; on the protocol's 7 held-out rows whose nearest label of their fence types lay 20 to 180 deg away it lay "
        "circular W1 12.0 deg from the simulator on average (median 7.0, 90th percentile 30.0); "
        "--simulate BUDGET asks the simulator"
    )
    assert "9 held-out rows with no label of their fence types it lay circular W1 14.0 deg" in model.describe(1)
    assert "4 held-out rows whose nearest label of their fence types lay 0 to 10 deg away" in model.describe(2)
    assert "held-out" not in model.describe(3)  # 15 deg: a bin without scored rows says nothing
    np.testing.assert_array_equal(model.structured_error_deg(), [12.0, 14.0, 2.5, np.nan])  # recommend's column
    lib.card = {k: v for k, v in lib.card.items() if k != "structured"}  # an older card
    assert "held-out" not in model.describe(0) and np.isnan(model.structured_error_deg()).all()


def test_the_card_says_when_the_shipped_seeds_were_trained_again_on_every_row():
    assert S._refit_words({"val_parts": 24}) == ""  # a file from before train.refit, or with it off
    assert S._refit_words({"refit_rows": 0}) == ""
    assert S._refit_words({"refit_rows": 1405}) == (
        ", then trained again on all 1405 kept rows for the steps early stopping kept"
    )


def test_the_card_names_the_fences_specialist_when_the_file_carries_one():
    from feeder.learn.study import _card_new_angle

    choice = {"kind": "variants", "hidden": 8, "weight_decay": 0.01, "val_parts": 24, "val_cw1": 9.43}
    st = {"choice": choice, "seeds": 3, "neighbours": 2, "cross_neighbours": 1, "evidence": [], "by_distance": []}
    card = {"gate_deg": 10.0, "structured": st}
    assert "Fences specialist" not in "\n".join(_card_new_angle(card))
    st["specialist"] = dict(choice, kind="candidates", hidden=32, val_cw1=11.5)
    text = "\n".join(_card_new_angle(card))
    assert "Fences specialist: candidates, hidden 32, weight decay 0.01, validation circular W1 11.50 deg" in text


def test_the_card_says_how_the_shipped_network_is_calibrated():
    from feeder.learn.study import _calibration_words, calibration_counts

    assert calibration_counts(None) is None and _calibration_words(None) == ""
    meta = {
        "margin_deg": 0.5,
        "modes": [{"name": "swing"}, {"name": "mu0.5"}, {"name": "never"}],
        "part_modes": {"a": "base", "b": "swing", "c": "swing", "d": "mu0.5"},
    }
    counts = calibration_counts(meta)
    assert counts == {"margin_deg": 0.5, "modes": 3, "parts": {"base": 1, "swing": 2, "mu0.5": 1}}
    words = _calibration_words(counts)
    assert "of 3 variants" in words and "(3 of 4 parts;" in words and "by 0.5 deg" in words


def test_the_card_says_how_the_answer_is_blended():
    from feeder.learn.study import NEAREST_WORDS, _blend_words

    assert _blend_words(None, "x") == "" and _blend_words({"weight": 1.0, "gate_deg": 5.0}, "x") == ""
    blend = {"weight": 0.6, "gate_deg": 7.5, "val_cw1": {"0.6": 7.1, "1.0": 7.9}}
    words = _blend_words(blend, NEAREST_WORDS)
    assert "0.6 times the network's plus 0.4 times the label of the nearest" in words
    assert "fence types within 7.5 degrees, else the analytic PMF" in words
    assert "(validation circular W1 7.10 against 7.90 deg alone)" in words
    words = _blend_words({"weight": 0.3, "gate_deg": None, "val_cw1": {}}, "the analytic PMF")
    assert "0.3 times the network's plus 0.7 times the analytic PMF, the weight chosen" in words
    assert "validation circular" not in words
    # blend.by_fallback: one weight where the fallback is a label, one where it is the analytic PMF
    split = {"weight": 0.4, "analytic_weight": 1.0, "gate_deg": 10.0, "val_cw1": {"1.0": 7.9}, "split_val_cw1": 6.5}
    words = _blend_words(split, NEAREST_WORDS)
    assert "0.4 times the network's plus 0.6 times the label of the nearest simulated angle" in words
    assert "within 10 degrees where there is one, else 1 times the network's plus 0 times the analytic PMF" in words
    assert "(validation circular W1 6.50 against 7.90 deg alone)" in words
    assert _blend_words({**split, "weight": 1.0, "analytic_weight": 0.5}, NEAREST_WORDS) != ""  # analytic rows alone


def test_the_card_says_the_mirrored_labels_are_read():
    from feeder.learn.study import _mirror_words, mirror_count

    assert _mirror_words(None) == ""
    assert mirror_count({"a": 180.0, "b": float("nan"), "c": 0.0}) == 2
    words = _mirror_words(2)
    assert "(2 of its parts) is also read at the other location, reflected" in words
