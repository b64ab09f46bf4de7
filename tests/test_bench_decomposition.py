"""feeder bench-decomposition and bench-decomposition-table (issue #37 item 1): the alternative
convex decompositions are valid, the bench simulates them as given, the pass rule, the table from
the raw drops, and the test's verdicts on two small parts."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
from shapely.geometry import Polygon
from shapely.ops import unary_union

from feeder.bench import decomposition as D
from feeder.bench import decomposition_table as T
from feeder.errors import FeederError
from feeder.parts.geometry import PartGeometry, is_convex

RECT = np.array([[0.0, 0.0], [0.075, 0.0], [0.075, 0.025], [0.0, 0.025]])
ELL = np.array([[0.0, 0.0], [0.060, 0.0], [0.060, 0.012], [0.012, 0.012], [0.012, 0.040], [0.0, 0.040]])
TEE = np.array(
    [[0.02, 0.0], [0.032, 0.0], [0.032, 0.03], [0.052, 0.03], [0.052, 0.042], [0.0, 0.042], [0.0, 0.03], [0.02, 0.03]]
)
# a crescent-like many-piece outline: an arc band of 24 segments
_T = np.linspace(0.0, math.pi, 13)
CRESCENT = np.concatenate(
    [np.c_[0.03 * np.cos(_T), 0.03 * np.sin(_T)], np.c_[0.02 * np.cos(_T[::-1]), 0.012 * np.sin(_T[::-1])]]
)


def _part(outline, name="p"):
    return PartGeometry.from_polygon(name, outline, 0.008)


def _assert_tiles(outline, pieces):
    region = Polygon(outline)
    polys = [Polygon(p) for p in pieces]
    for p in pieces:
        assert is_convex(np.asarray(p)) or is_convex(np.asarray(p)[::-1])
    assert sum(p.area for p in polys) == pytest.approx(region.area, rel=1e-9)  # no overlap
    assert unary_union(polys).symmetric_difference(region).area <= 1e-9 * region.area  # no gap


@pytest.mark.parametrize(
    ("outline", "name", "count"),
    [
        (RECT, "triangles", 2),
        (RECT, "strips2", 2),
        (RECT, "strips3", 3),
        (RECT, "strips4", 4),
        (RECT, "fan", 4),
        (RECT, "library", 1),
        (ELL, "cut_in", 2),
        (ELL, "cut_out", 2),
        (ELL, "triangles", 4),
        (ELL, "library", 2),
        (TEE, "cut_in", 3),
        (TEE, "cut_out", 3),
        (CRESCENT, "greedy", None),
        (CRESCENT, "strips3", None),
        (CRESCENT, "triangles", len(CRESCENT) - 2),
    ],
)
def test_each_decomposition_is_convex_pieces_tiling_the_part(outline, name, count):
    pieces = D.decompose(_part(outline), name, 0.0)
    if count is not None:
        assert len(pieces) == count
    _assert_tiles(outline, pieces)


def test_the_l_is_cut_one_way_and_the_other_into_two_rectangles():
    part = _part(ELL)
    cut_in, cut_out = D.decompose(part, "cut_in", 0.0), D.decompose(part, "cut_out", 0.0)
    boxes = lambda pieces: sorted(tuple(np.round(Polygon(p).bounds, 9)) for p in pieces)  # noqa: E731
    assert boxes(cut_in) != boxes(cut_out)
    for pieces in (cut_in, cut_out):  # each piece fills its bounding box: a rectangle
        assert all(Polygon(p).area == pytest.approx(Polygon(p).envelope.area, rel=1e-9) for p in pieces)
    assert boxes(cut_in) == [(0.0, 0.0, 0.06, 0.012), (0.0, 0.012, 0.012, 0.04)]


def test_strips_cut_across_the_long_axis():
    pieces = D.strips(RECT, 3)
    widths = sorted(Polygon(p).bounds[2] - Polygon(p).bounds[0] for p in pieces)
    assert widths == pytest.approx([0.025] * 3)


def test_library_parts_decompose_validly():
    from feeder.parts.geometry import load_part

    for part, names in (("gear8-a", ["strips2", "greedy"]), ("crescent-a", ["greedy"])):
        geom = load_part(f"parts/{part}.stl")
        for name in names:
            pieces = D.decompose(geom, name, 0.0)
            _assert_tiles(geom.outline, pieces)
        assert len(D.decompose(geom, "library", 0.0)) == len(geom.convex_pieces)


def test_check_decomposition_refuses_overlap_gap_and_a_concave_piece():
    half = [RECT[[0, 1, 2]], RECT[[0, 2, 3]]]
    D.check_decomposition(RECT, half)
    with pytest.raises(FeederError, match="tile"):
        D.check_decomposition(RECT, [RECT, RECT[[0, 1, 2]]])  # overlap
    with pytest.raises(FeederError, match="tile"):
        D.check_decomposition(RECT, half[:1])  # gap
    with pytest.raises(FeederError, match="convex"):
        D.check_decomposition(ELL, [ELL])
    with pytest.raises(FeederError, match="not convex"):
        D.fan(ELL)
    with pytest.raises(FeederError, match="no reflex"):
        D.reflex_cuts(RECT, "in")
    with pytest.raises(FeederError, match="decomposition 'bogus'"):
        D.decompose(_part(RECT), "bogus", 0.0)


def test_the_pieces_are_simulated_as_given_not_merged_back():
    """At tolerance 0 the part model fuses a rectangle's two triangles back into one piece; with
    merge_tolerance None (what the bench's runs use) it keeps them."""
    from feeder.config import load_study_config
    from feeder.sim.body import part_model

    scene = load_study_config("config/config.yaml")["scene"]
    part = D.with_pieces(_part(RECT), D.triangles(RECT))
    assert len(part_model(part, scene, 0.0).pieces) == 1
    assert len(part_model(part, scene, None).pieces) == 2


# ----------------------------------------------------------------------------------------------
# The pass rule and the table (pure)
# ----------------------------------------------------------------------------------------------
FLOOR = {"same_basin": 0.95, "median_dyaw_deg": 0.1, "sup_cdf": 0.05, "circular_w1_deg": 1.0}


@pytest.mark.parametrize(
    ("row", "paired", "label"),
    [
        ({"same_basin": 0.9, "median_dyaw_deg": 0.2, "sup_cdf": 0.1, "circular_w1_deg": 2.0}, True, True),
        ({"same_basin": 0.85, "median_dyaw_deg": 0.2, "sup_cdf": 0.1, "circular_w1_deg": 2.0}, False, True),
        ({"same_basin": 1.0, "median_dyaw_deg": 0.21, "sup_cdf": 0.1, "circular_w1_deg": 2.0}, False, True),
        ({"same_basin": 1.0, "median_dyaw_deg": 0.0, "sup_cdf": 0.11, "circular_w1_deg": 0.0}, True, False),
        ({"same_basin": 1.0, "median_dyaw_deg": 0.0, "sup_cdf": 0.0, "circular_w1_deg": 2.1}, True, False),
        ({"same_basin": 1.0, "median_dyaw_deg": math.nan, "sup_cdf": 0.0, "circular_w1_deg": 0.0}, False, True),
    ],
)
def test_a_comparison_passes_within_the_factor_times_its_floor(row, paired, label):
    assert T.within_floor(row, FLOOR, 40, 2.0, T.PAIRED) is paired
    assert T.within_floor(row, FLOOR, 40, 2.0, T.LABEL) is label
    assert T.within_floor(row, FLOOR, 40, 2.0) is (paired and label)


def test_label_resolution_by_hand():
    assert T.label_resolution(360, 32) == {"median_dyaw_deg": 0.5, "sup_cdf": 1 / 32, "circular_w1_deg": 1 / 32}
    assert T.label_resolution(90, 8)["circular_w1_deg"] == pytest.approx(0.5)
    own = {"same_basin": 1.0, "median_dyaw_deg": 1e-6, "sup_cdf": 0.2, "circular_w1_deg": math.nan}
    floor = T.resolved_floor(own, 360, 32)
    assert floor["same_basin"] == 1.0 and floor["median_dyaw_deg"] == 0.5  # raised
    assert floor["sup_cdf"] == 0.2 and math.isnan(floor["circular_w1_deg"])  # kept


def test_a_perfect_floor_still_allows_one_missed_drop_per_factor():
    perfect = {"same_basin": 1.0, "median_dyaw_deg": 0.1, "sup_cdf": 0.05, "circular_w1_deg": 1.0}
    row = dict(perfect)
    assert T.within_floor(row | {"same_basin": 1 - 2 / 40}, perfect, 40, 2.0, T.PAIRED)
    assert not T.within_floor(row | {"same_basin": 1 - 3 / 40}, perfect, 40, 2.0, T.PAIRED)
    nan = {k: math.nan for k in perfect}
    assert T.within_floor(nan | {"same_basin": 1.0}, nan | {"same_basin": 1.0}, 40, 2.0)


def _raw(final_by_run, drops=8, cpu=0.8):
    """Raw drops of one part and configuration: {(model, decomposition, offset, shift): finals}."""
    rows = []
    for (model, name, tag, shift), finals in final_by_run.items():
        for i, y in enumerate(finals):
            rows.append(
                {
                    "part": "p",
                    "configuration": "straight:30|none",
                    "model": model,
                    "decomposition": name,
                    "offset": tag,
                    "yaw_shift_deg": shift,
                    "pieces": 1 if name == "library" else 3,
                    "drop": i,
                    "initial_yaw_deg": 0.0,
                    "final_yaw_deg": y,
                    "status": "ok",
                    "cpu_s": cpu,
                }
            )
    return pd.DataFrame(rows)


def test_summarize_gives_each_model_its_floor_and_a_verdict():
    base = np.array([10.0, 100.0, 190.0, 280.0, 10.5, 100.5, 190.5, 280.5])
    runs = {}
    for model, moved in (("pieces", 4.0), ("pads8", 0.02), ("pads16", 0.02)):
        runs |= {
            (model, "library", "a", 0.0): base,
            (model, "library", "a", 0.01): base + 0.05,
            (model, "library", "b", 0.0): base + 1.0,
            (model, "strips3", "a", 0.0): base + moved,
        }
    table = T.summarize(_raw(runs), 360, 1.0, 2.0)
    rows = table[table["kind"] == "decomposition"].set_index("model")
    assert rows.loc["pieces", "median_dyaw_deg"] == pytest.approx(4.0)
    assert rows.loc["pieces", "own_floor_median_dyaw_deg"] == pytest.approx(0.05)
    assert rows.loc["pieces", "floor_median_dyaw_deg"] == pytest.approx(0.5)  # raised to half a 1-degree bin
    assert not rows.loc["pieces", "passes"] and rows.loc["pads8", "passes"]
    verdict = table[table["kind"] == "verdict"].set_index("model")
    assert verdict.loc["pieces", "rows"] == 1 and not verdict.loc["pieces", "passes"]
    assert verdict.loc["pads8", "passes"] and verdict.loc["pads8", "cpu_ms_per_drop"] == pytest.approx(100.0)
    converge = table[table["kind"] == "convergence"]
    assert set(converge["model"]) == {"pads8~pads16"} and converge["passes"].all()
    assert verdict.loc["pads8~pads16", "decomposition_a"] == "convergence"


# ----------------------------------------------------------------------------------------------
# The verdicts on two small parts (real simulations, `fast`, a few drops)
# ----------------------------------------------------------------------------------------------
def _bench(part, names, config, drops=6, models=("pieces", "pads8")):
    return {
        "parts": {part: names},
        "configurations": [config],
        "models": list(models),
        "drops": drops,
        "sampling": "grid",
        "offset_b_seed": 1,
        "nudge_deg": 0.01,
        "floor_factor": 2.0,
        "preset": "fast",
        "workers": 1,
    }


def test_cli_makes_the_table_from_raw_drops_alone(tmp_path, capsys):
    from feeder.cli import main as cli
    from feeder.config import load_study_config

    cfg = load_study_config("config/config.yaml")
    runs = {(m, n, t, s): np.array([10.0, 100.0]) + s for m in ("pieces", "pads8", "pads16") for n, t, s in D_PLAN}
    raw = tmp_path / "raw.csv"
    _raw(runs, cpu=0.2).to_csv(raw, index=False)
    settings = {
        "scene": cfg["scene"],
        "sim": {
            "presets": cfg["sim"]["presets"],
            "base_seed": 0,
            "decomposition_bench": cfg["sim"]["decomposition_bench"],
        },
        "parts": cfg["parts"],
        "labels": cfg["labels"],
    }
    out = tmp_path / "t.csv"
    args = ["bench-decomposition-table", "--settings", json.dumps(settings), "--raw", str(raw), "--out-csv", str(out)]
    assert cli(args) == 0
    table = pd.read_csv(out)
    assert set(table["kind"]) == {"decomposition", "convergence", "verdict"}
    assert "passes" in capsys.readouterr().err
    again = tmp_path / "t2.csv"
    assert cli([*args[:-1], str(again)]) == 0
    assert again.read_bytes() == out.read_bytes()  # the same raw drops, the same table, bit for bit
    missing = ["bench-decomposition-table", "--settings", json.dumps({"sim": {}}), "--raw", str(raw)]
    assert cli([*missing, "--out-csv", str(tmp_path / "none.csv")]) == 2
    assert not (tmp_path / "none.csv").exists()


D_PLAN = [("library", "a", 0.0), ("library", "a", 0.01), ("library", "b", 0.0), ("fan", "a", 0.0)]


@pytest.fixture(scope="module")
def study():
    from feeder.config import load_study_config
    from feeder.sim.drops import get_preset

    cfg = load_study_config("config/config.yaml")
    return cfg["scene"], get_preset(cfg["sim"]["presets"], "fast"), cfg["labels"]


@pytest.mark.parametrize(
    ("part", "other", "config", "pieces_label"),
    [("rect-a3", "strips3", "straight:30|none", False), ("lshape-a", "cut_in", "straight:45|none", True)],
)
def test_verdicts_on_two_small_parts(study, part, other, config, pieces_label):
    """The same drops under two decompositions, in the default scene (round fence tips since
    2026-11-29): the pieces move every drop by 1.2-4.2 degrees, 10-90 x their nudged floor, 7-14 x
    what pads move them and more than twice half a label bin (the paired test fails), and on the
    rectangle (cut in three strips) the label too; pads move the drops by 0.18-0.30 degrees through
    the pieces' fence contacts, above their measured floor of 0.0001 degrees or less but within the
    label's resolution (half a bin): they pass. The thresholds below sit at half the smaller measured
    ratio (under the square tip these were written for, 20 x and 10 x held). With six drops the L's
    label floor (a second offset) is 14 degrees of W1, which the pieces' 1.2 degrees pass."""
    scene, preset, labels = study
    bench = _bench(part, [other], config, models=("pieces", "pads8", "pads8+outline"))
    raw = D.simulate_all(bench, 0, "parts", scene, preset, 1)
    table = T.summarize(raw, int(labels["bins"]), float(labels["sigma_bins"]), 2.0)
    rows = table[table["kind"] == "decomposition"].set_index("model")
    assert len(rows) == 3 and (rows["decomposition_b"] == other).all()
    # pads with outline slabs: walls and fences never see the decomposition, every drop repeats exactly
    outline = rows.loc["pads8+outline"]
    assert (outline["same_basin"], outline["median_dyaw_deg"], outline["sup_cdf"]) == (1.0, 0.0, 0.0)
    assert outline["circular_w1_deg"] == 0.0 and outline["passes"]
    runs = raw[(raw["model"] == "pads8+outline") & (raw["offset"] == "a") & (raw["yaw_shift_deg"] == 0)]
    by = {n: g.sort_values("drop")["final_yaw_deg"].to_numpy() for n, g in runs.groupby("decomposition")}
    assert np.array_equal(by["library"], by[other], equal_nan=True)
    pieces, pads = rows.loc["pieces"], rows.loc["pads8"]
    assert (pieces["same_basin"], pads["same_basin"]) == (1.0, 1.0)
    assert pieces["median_dyaw_deg"] > 5 * pieces["own_floor_median_dyaw_deg"]
    assert pieces["median_dyaw_deg"] > 1.0 and pieces["median_dyaw_deg"] > 4 * pads["median_dyaw_deg"]
    assert pads["median_dyaw_deg"] > 2 * pads["own_floor_median_dyaw_deg"]  # measurable, below a bin
    assert not pieces["passes_paired"] and pads["passes_paired"]
    assert bool(pieces["passes_label"]) is pieces_label and pads["passes_label"]
    verdict = table[table["kind"] == "verdict"].set_index("model")
    assert not verdict.loc["pieces", "passes"] and verdict.loc["pads8", "passes"]
    assert verdict.loc["pads8+outline", "passes"]


def test_the_bench_runs_the_pieces_it_is_given(study, monkeypatch):
    """run_decomposition hands the part model its pieces unmerged: the two triangles of a rectangle
    reach the world as two pieces, not fused back into one."""
    import feeder.sim.drops as drops

    scene, preset, _ = study
    built = []
    real = drops.part_model
    monkeypatch.setattr(drops, "part_model", lambda *a, **k: built.append(real(*a, **k)) or built[-1])
    D.run_decomposition(
        _part(RECT), D.triangles(RECT), "straight:30|none", [0.0], D.model_scene(scene, "pieces"), preset
    )
    assert built and all(len(m.pieces) == 2 for m in built)
