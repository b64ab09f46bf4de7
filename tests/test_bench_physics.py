"""feeder bench-physics and bench-physics-table (issue #37 item 3): factors applied to the settings,
bad factors refused, the table's statistics on hand-made drops, a small end-to-end run, and the
hard cases (near tipping on pads, thin, holed, a fence near the friction limit) under every factor."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from feeder.bench import physics as P
from feeder.bench import physics_table as T
from feeder.errors import FeederError
from feeder.parts.geometry import PartGeometry

RECT = np.array([[0.0, 0.0], [0.04, 0.0], [0.04, 0.02], [0.0, 0.02]])


@pytest.fixture(scope="module")
def study():
    from feeder.config import load_study_config
    from feeder.sim.drops import get_preset

    cfg = load_study_config("config/config.yaml")
    return cfg, get_preset(cfg["sim"]["presets"], cfg["sim"]["physics_bench"]["preset"])


def _geom(thickness=0.008):
    return PartGeometry.from_polygon("r", RECT, thickness)


# ----------------------------------------------------------------------------------------------
# Factors (pure)
# ----------------------------------------------------------------------------------------------
def test_a_scaled_scene_number_is_a_copy_times_the_scale(study):
    cfg, preset = study
    scene = cfg["scene"]
    g, s, p = P.apply_factor({"name": "f", "path": "scene.part.friction", "scale": 0.8}, _geom(), scene, preset)
    assert s["part"]["friction"] == pytest.approx(0.8 * scene["part"]["friction"])
    assert scene["part"]["friction"] == 0.8  # the default is untouched
    assert s["fences"] == scene["fences"] and p == preset and g.thickness == 0.008
    _, s, _ = P.apply_factor({"name": "e", "path": "scene.restitution", "value": 0.1}, _geom(), scene, preset)
    assert s["restitution"] == 0.1 and scene["restitution"] == 0.0
    _, s, _ = P.apply_factor({"name": "v", "path": "scene.belt.speed", "scale": 1.25}, _geom(), scene, preset)
    assert s["belt"]["speed"] == pytest.approx(0.125)


def test_half_the_step_doubles_the_substeps_and_keeps_an_integer(study):
    cfg, preset = study
    _, s, p = P.apply_factor({"name": "h", "path": "preset.substeps", "scale": 2}, _geom(), cfg["scene"], preset)
    assert (
        p["substeps"] == 2 * preset["substeps"]
        and isinstance(p["substeps"], int)
        and p["time_step"] == preset["time_step"]
    )
    assert preset["substeps"] == cfg["sim"]["presets"][cfg["sim"]["physics_bench"]["preset"]]["substeps"]  # untouched
    assert s == cfg["scene"]
    with pytest.raises(FeederError, match="integer"):
        P.apply_factor({"name": "h", "path": "preset.substeps", "scale": 1.25}, _geom(), cfg["scene"], preset)


def test_thickness_moves_the_part_and_its_mass_not_the_scene(study):
    from feeder.sim.body import part_model

    cfg, preset = study
    geom = _geom()
    g, s, _ = P.apply_factor({"name": "t", "path": "part.thickness", "scale": 1.2}, geom, cfg["scene"], preset)
    assert g.thickness == pytest.approx(0.0096) and geom.thickness == 0.008 and s == cfg["scene"]
    assert g.area == geom.area and g.outline is geom.outline
    m0, m1 = part_model(geom, cfg["scene"]).mass, part_model(g, cfg["scene"]).mass
    assert m1 == pytest.approx(1.2 * m0)
    _, s, _ = P.apply_factor({"name": "d", "path": "scene.part.density", "scale": 1.2}, geom, cfg["scene"], preset)
    assert part_model(geom, s).mass == pytest.approx(1.2 * m0)


def test_the_contact_model_factor_sets_pads_and_outline_walls(study):
    cfg, preset = study
    f = {"name": "c", "path": "contact_model", "value": "pads8+outline"}
    _, s, _ = P.apply_factor(f, _geom(), cfg["scene"], preset)
    assert s["belt"]["footprint"]["model"] == "pads" and s["belt"]["footprint"]["pads"] == 8
    assert s["part"]["wall_contact"]["model"] == "outline"
    assert cfg["scene"]["belt"]["footprint"]["pads"] == 16  # the default's, untouched
    _, s, _ = P.apply_factor(dict(f, value="pieces"), _geom(), cfg["scene"], preset)
    assert s["belt"]["footprint"]["model"] == "pieces" and s["part"]["wall_contact"]["model"] == "pieces"
    assert cfg["scene"]["belt"]["footprint"]["model"] == "pads"


@pytest.mark.parametrize(
    "factor, message",
    [
        ({"name": "x", "path": "scene.belt.grip", "scale": 0.8}, "unknown path"),
        ({"name": "x", "path": "scene.part.friction.mu", "scale": 0.8}, "unknown path"),
        ({"name": "x", "path": "gravity", "scale": 0.8}, "unknown path"),
        ({"name": "x", "path": "part.area", "scale": 0.8}, "unknown path"),
        ({"name": "x", "path": "scene.part.friction", "scale": 0}, "positive"),
        ({"name": "x", "path": "scene.part.friction", "scale": -1.2}, "positive"),
        ({"name": "x", "path": "scene.part.friction", "scale": 0.8, "value": 1.0}, "not both"),
        ({"name": "x", "path": "scene.part.friction"}, "not neither"),
        ({"name": "x", "path": "scene.mirror", "scale": 2}, "not a number"),
        ({"name": "x", "path": "contact_model", "value": "springs"}, "contact model"),
        ({"name": "baseline", "path": "scene.part.friction", "scale": 0.8}, "unmoved"),
    ],
)
def test_a_bad_factor_is_a_one_line_error(study, factor, message):
    cfg, preset = study
    with pytest.raises(FeederError, match=message) as err:
        P.apply_factor(factor, _geom(), cfg["scene"], preset)
    assert "\n" not in str(err.value)


def test_every_factor_is_checked_on_every_part_before_anything_runs(study):
    cfg, preset = study
    thin = {"name": "t", "path": "part.thickness", "scale": 0.1}  # 0.8 mm: under the fences' clearance x 2
    with pytest.raises(FeederError, match="thinner"):
        P.check_factors([thin], {"r": _geom()}, cfg["scene"], preset)
    f = {"name": "a", "path": "scene.part.friction", "scale": 0.8}
    with pytest.raises(FeederError, match="named twice"):
        P.check_factors([f, f], {"r": _geom()}, cfg["scene"], preset)
    P.check_factors(cfg["sim"]["physics_bench"]["factors"], {"r": _geom()}, cfg["scene"], preset)


def test_the_plan_pairs_every_run_on_the_same_initial_yaws(study):
    cfg, _ = study
    bench = dict(cfg["sim"]["physics_bench"], configurations=[["rect-a2", "straight:30|none"]], drops=4)
    runs = P.plan_runs(bench)
    a = [r for r in runs if r["offset"] == "a" and r["yaw_shift_deg"] == 0]
    assert len(a) == 1 + len(bench["factors"]) and len(runs) == len(a) + 2
    for r in a:
        np.testing.assert_array_equal(r["yaws"], a[0]["yaws"])
    nudged = next(r for r in runs if r["yaw_shift_deg"] != 0)
    np.testing.assert_allclose(nudged["yaws"] - a[0]["yaws"], 0.01)
    b = next(r for r in runs if r["offset"] == "b")
    assert not np.allclose(b["yaws"], a[0]["yaws"])
    assert {r["level"] for r in a} >= {"x0.8", "x1.2", "=0.1", "=pieces", "x2"}


# ----------------------------------------------------------------------------------------------
# The table (pure)
# ----------------------------------------------------------------------------------------------
def test_bootstrap_interval_by_hand():
    assert T.bootstrap_interval([2.0, 2.0, 2.0], "median", 100, 0) == (2.0, 2.0, 2.0)
    est, low, high = T.bootstrap_interval([0.0, 1.0, np.nan], "mean", 500, 0)
    assert est == 0.5 and 0.0 <= low < 0.5 < high <= 1.0  # the NaN is left out
    est, low, high = T.bootstrap_interval([1.0, 2.0, 3.0, 4.0, 100.0], "median", 500, 0)
    assert est == 3.0 and low >= 1.0 and high <= 100.0
    assert all(math.isnan(v) for v in T.bootstrap_interval([np.nan], "median", 10, 0))
    assert T.bootstrap_interval([1.0, 5.0], "mean", 50, 3) == T.bootstrap_interval([1.0, 5.0], "mean", 50, 3)
    with pytest.raises(FeederError):
        T.bootstrap_interval([1.0], "mode", 10, 0)


BASE = np.array([10.0, 100.0, 200.0, 300.0])


def _raw(shift: dict, status=None) -> pd.DataFrame:
    """Hand-made drops of two configurations: the baseline at BASE, nudged by 0.05 deg, offset b at
    BASE + 1; the factor ``f`` at BASE + shift[configuration]."""
    rows = []
    for config, move in shift.items():
        for factor, offset, nudge, final in (
            ("baseline", "a", 0.0, BASE),
            ("baseline", "a", 0.01, BASE + 0.05),
            ("baseline", "b", 0.0, BASE + 1.0),
            ("f", "a", 0.0, BASE + move),
        ):
            st = (status or {}).get((config, factor), ["ok"] * len(BASE))
            for i, (y, s) in enumerate(zip(final, st)):
                rows.append(
                    {
                        "part": "p",
                        "configuration": config,
                        "factor": factor,
                        "path": "" if factor == "baseline" else "scene.part.friction",
                        "level": "" if factor == "baseline" else "x0.8",
                        "offset": offset,
                        "yaw_shift_deg": nudge,
                        "drop": i,
                        "initial_yaw_deg": 0.0,
                        "final_yaw_deg": y if s == "ok" else np.nan,
                        "status": s,
                        "cpu_s": 1.0 if factor == "baseline" else 2.0,
                    }
                )
    return pd.DataFrame(rows)


def test_the_table_by_hand():
    # every drop of the factor 2 deg later in one configuration, 4 deg in the other: two and four
    # 1-degree bins, so circular W1 2 and 4, median |dyaw| 2 and 4, every drop in the same basin (< 5 deg)
    table = T.summarize(_raw({"s1|none": 2.0, "s2|none": 4.0}), 360, 1.0, 200, 0, order=["f"])
    per = table[table["kind"] == "configuration"].set_index("configuration")
    assert per.loc["s1|none", "circular_w1_deg"] == pytest.approx(2.0)
    assert per.loc["s2|none", "circular_w1_deg"] == pytest.approx(4.0)
    assert per.loc["s2|none", "median_dyaw_deg"] == pytest.approx(4.0) and per.loc["s2|none", "same_basin"] == 1.0
    assert per.loc["s1|none", "floor_circular_w1_deg"] == pytest.approx(1.0)  # offset b: one bin later
    assert per.loc["s1|none", "floor_median_dyaw_deg"] == pytest.approx(0.05)
    assert per.loc["s1|none", "ok_nan"] == 0 and per.loc["s1|none", "ok_rate"] == 1.0
    assert per.loc["s2|none", "circular_w1_to_floor"] == pytest.approx(4.0)
    f = table[table["kind"] == "factor"].iloc[0]
    assert f["factor"] == "f" and f["path"] == "scene.part.friction" and f["level"] == "x0.8"
    assert f["circular_w1_deg_median"] == pytest.approx(3.0) and f["circular_w1_deg_mean"] == pytest.approx(3.0)
    assert 2.0 - 1e-9 <= f["circular_w1_deg_median_low"] <= 3.0 <= f["circular_w1_deg_median_high"] <= 4.0 + 1e-9
    assert f["cpu_ratio"] == pytest.approx(2.0) and f["configurations"] == 2
    assert f["circular_w1_to_floor_median"] == pytest.approx(3.0)
    floor = table[table["kind"] == "floor"].iloc[0]
    assert floor["circular_w1_deg_median"] == pytest.approx(1.0) and floor["median_dyaw_deg_median"] == pytest.approx(
        0.05
    )
    assert list(table["kind"].drop_duplicates()) == ["factor", "floor", "configuration"]


def test_a_floor_of_zero_is_raised_to_the_labels_resolution():
    raw = _raw({"s1|none": 2.0, "s2|none": 2.0})
    raw.loc[(raw["offset"] == "b"), "final_yaw_deg"] -= 1.0  # offset b ends exactly where offset a does
    per = T.configuration_rows(raw, 360, 1.0)
    assert (per["floor_circular_w1_deg"] == 0).all()
    assert per["circular_w1_to_floor"].to_numpy() == pytest.approx(2.0 / (1.0 / 4))  # one drop of 4 moved one bin


def test_the_table_counts_jams_and_an_ok_drop_without_a_yaw():
    status = {("s1|none", "f"): ["ok", "jammed", "jammed", "ok"]}
    raw = _raw({"s1|none": 0.0, "s2|none": 0.0}, status)
    per = T.configuration_rows(raw, 360, 1.0).set_index("configuration")
    assert per.loc["s1|none", "ok_rate"] == 0.5 and per.loc["s1|none", "same_basin"] == 0.5
    raw.loc[(raw["configuration"] == "s2|none") & (raw["factor"] == "f") & (raw["drop"] == 0), "final_yaw_deg"] = np.nan
    per = T.configuration_rows(raw, 360, 1.0).set_index("configuration")
    assert per.loc["s2|none", "ok_nan"] == 1


def test_model_errors_are_read_from_the_committed_tables(tmp_path):
    errors = T.model_errors(
        [{"name": "m3 Test", "table": "results/tables/table6.csv", "row": "m3", "column": "cw1_mean"}]
    )
    t6 = pd.read_csv("results/tables/table6.csv").set_index("model")
    assert errors[0]["value"] == pytest.approx(t6.loc["m3", "cw1_mean"]) and "table6.csv" in errors[0]["source"]
    with pytest.raises(FeederError, match="no row"):
        T.model_errors([{"name": "x", "table": "results/tables/table6.csv", "row": "m99", "column": "cw1_mean"}])
    assert T.model_errors([{"name": "x", "table": str(tmp_path / "none.csv"), "row": "m3", "column": "cw1_mean"}]) == []
    (tmp_path / "bad.csv").write_text("model,cw1_mean\nm3,1.0\n")
    with pytest.raises(FeederError, match="x"):
        T.model_errors([{"name": "x", "table": str(tmp_path / "bad.csv"), "row": "m3", "column": "other"}])


# ----------------------------------------------------------------------------------------------
# End to end (real simulations, `fast`, a few drops) and bad input
# ----------------------------------------------------------------------------------------------
def _settings(cfg, **bench) -> dict:
    physics = dict(cfg["sim"]["physics_bench"], **bench)
    return {
        "scene": cfg["scene"],
        "sim": {"presets": cfg["sim"]["presets"], "physics_bench": physics},
        "parts": cfg["parts"],
        "labels": cfg["labels"],
    }


SMALL = {
    "configurations": [["rect-a2", "straight:30|none"], ["lshape-a", "none|curved:40"]],
    "factors": [
        {"name": "fence_friction_x0.8", "path": "scene.fences.friction", "scale": 0.8},
        {"name": "thickness_x1.2", "path": "part.thickness", "scale": 1.2},
    ],
    "drops": 2,
    "bootstrap": 50,
    "workers": 1,
}


def test_end_to_end_raw_drops_table_and_figure(study, tmp_path, capsys):
    from feeder.cli import main as cli

    cfg, _ = study
    settings = json.dumps(_settings(cfg, **SMALL))
    raw, table, png = tmp_path / "raw.csv", tmp_path / "t.csv", tmp_path / "f.png"
    assert cli(["bench-physics", "--settings", settings, "--out-raw", str(raw)]) == 0
    drops = pd.read_csv(raw)
    assert len(drops) == 2 * (3 + 2) * 2
    assert set(drops["factor"]) == {"baseline", "fence_friction_x0.8", "thickness_x1.2"}
    ok = drops["status"] == "ok"
    assert np.isfinite(drops.loc[ok, "final_yaw_deg"]).all()
    for _, g in drops[drops["offset"] == "a"].groupby(["configuration", "yaw_shift_deg"]):
        assert g.groupby("drop")["initial_yaw_deg"].nunique().max() == 1  # paired: one initial yaw per drop
    assert cli(["bench-physics-table", "--settings", settings, "--raw", str(raw), "--out-csv", str(table)]) == 0
    t = pd.read_csv(table)
    assert list(t.loc[t["kind"] == "factor", "factor"]) == ["fence_friction_x0.8", "thickness_x1.2"]
    assert (t["kind"] == "configuration").sum() == 4 and (t["kind"] == "model_error").sum() == 3
    assert "circular W1" in capsys.readouterr().err
    again = tmp_path / "t2.csv"
    assert cli(["bench-physics-table", "--settings", settings, "--raw", str(raw), "--out-csv", str(again)]) == 0
    assert again.read_bytes() == table.read_bytes()
    assert cli(["figure", "physics_sensitivity", "--data", str(table), "--out", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    "factor",
    [
        {"name": "bad", "path": "scene.belt.grip", "scale": 0.8},
        {"name": "bad", "path": "scene.belt.friction", "scale": 0.0},
        {"name": "bad", "path": "scene.belt.friction", "scale": -0.8},
    ],
)
def test_bad_input_is_one_line_nonzero_and_writes_nothing(study, tmp_path, capsys, factor):
    from feeder.cli import main as cli

    cfg, _ = study
    settings = json.dumps(_settings(cfg, **dict(SMALL, factors=[factor])))
    raw = tmp_path / "raw.csv"
    assert cli(["bench-physics", "--settings", settings, "--out-raw", str(raw)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "bad" in err
    assert not raw.exists() and not list(tmp_path.iterdir())


# ----------------------------------------------------------------------------------------------
# Hard cases: a label or a counted status under every factor, never an ok drop without a yaw
# ----------------------------------------------------------------------------------------------
def _every_factor(study, part, config, drops=2, base_model=None):
    from feeder.bench.decomposition import model_scene
    from feeder.sim.drops import STATUSES

    cfg, preset = study
    scene = cfg["scene"] if base_model is None else model_scene(cfg["scene"], base_model)
    bench = dict(cfg["sim"]["physics_bench"], configurations=[[part, config]], drops=drops)
    P.check_bench(bench, cfg["parts"]["dir"], scene, preset)
    seen = {}
    for run in P.plan_runs(bench):
        if run["offset"] != "a" or run["yaw_shift_deg"] != 0:
            continue
        _, out = P._job((run, cfg["parts"]["dir"], scene, preset))
        final, status = out["final_yaw_deg"], out["status"]
        assert set(status) <= set(STATUSES) and "nan" not in set(status), (run["factor"], status)
        assert np.isfinite(final[status == "ok"]).all(), (run["factor"], final, status)
        assert np.isnan(final[status != "ok"]).all(), (run["factor"], final, status)
        seen[run["factor"]] = list(status)
    assert len(seen) == 1 + len(bench["factors"])
    return seen


def test_a_bar_near_tipping_over_on_pads_under_every_factor(study):
    # rect-a8 (112 x 14 x 10 mm): the default's 16 pads' hull is 5.2 mm from its centroid, half its
    # thickness (8 pads: 3.5 mm, a third); on pads under every factor, thickness x 1.2 included, and on 8 pads
    assert study[0]["scene"]["belt"]["footprint"] == dict(study[0]["scene"]["belt"]["footprint"], model="pads", pads=16)
    _every_factor(study, "rect-a8", "straight:45|none")
    _every_factor(study, "rect-a8", "straight:45|none", base_model="pads8+outline")


def test_a_thin_part_under_every_factor(study):
    _every_factor(study, "tri-sliver", "none|straight:50")  # 5 mm thick, 4 mm at thickness x 0.8


def test_a_part_with_holes_under_every_factor(study):
    _every_factor(study, "holed-frame-1", "curved:40|none")


def test_a_fence_near_the_friction_limit_under_every_factor(study):
    # a straight fence at 65 deg, mu = 0.8 x 0.5 = 0.4 (it holds a part beyond 68.2 deg); fence
    # friction x 1.2 gives mu 0.48, whose limit is 64.4 deg: the part may stick, and that is counted
    _every_factor(study, "rect-a2", "straight:65|none")
