"""feeder bench-step: what one simulation step costs against a bare one-box world."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from feeder.bench import step
from feeder.config import load_study_config
from feeder.errors import FeederError
from feeder.lane.fences import parse_location
from feeder.parts.geometry import load_part
from feeder.sim.drops import get_preset

ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]
CONFIG = load_study_config(root=ROOT)
SCENE = CONFIG["scene"]
FAST = get_preset(CONFIG["sim"]["presets"], "fast")


def test_mean_interval_is_the_student_t_interval_by_hand():
    mean, low, high = step.mean_interval([1.0, 2.0, 3.0])
    half = 4.302652729911275 / math.sqrt(3.0)  # t(0.975, 2) * sd 1 / sqrt(3)
    assert (mean, low, high) == pytest.approx((2.0, 2.0 - half, 2.0 + half))
    assert step.mean_interval([5.0])[0] == 5.0 and all(map(math.isnan, step.mean_interval([5.0])[1:]))
    with pytest.raises(FeederError, match="finite"):
        step.mean_interval([1.0, float("nan")])


def test_contact_fit_is_the_least_squares_line():
    assert step.contact_fit([3.0, 5.0, 7.0], [2, 4, 6]) == pytest.approx((1.0, 1.0))
    assert step.contact_fit([3.0, 5.0, 4.0], [4, 4, 4]) == (pytest.approx(math.nan, nan_ok=True),) * 2


def _raw():
    """Substeps 10. Bare: repeats 0 and 1, two calls each of 100 and 120 us (4 points). Drops:
    repeat 0 two calls of 200 us (4 points) and 400 us (8); repeat 1 two of 300 us (6)."""
    rows = [("p", "", "bare", r, k, 1e-4 if k == 0 else 1.2e-4, 4) for r in (0, 1) for k in (0, 1)]
    rows += [("p", "a|b", "drop", 0, 0, 2e-4, 4), ("p", "a|b", "drop", 0, 1, 4e-4, 8)]
    rows += [("p", "a|b", "drop", 1, k, 3e-4, 6) for k in (0, 1)]
    raw = pd.DataFrame(rows, columns=["part", "configuration", "world", "repeat", "call", "cpu_s", "contact_points"])
    # the plain runs took 8e-4 and 7.5e-4 s over the same two calls each
    plain = pd.DataFrame({"part": "p", "configuration": "a|b", "repeat": [0, 1], "cpu_s": [8e-4, 7.5e-4], "calls": 2})
    return raw, plain


def test_summary_by_hand():
    raw, plain = _raw()
    table = step.summarize(raw, plain, substeps=10).set_index("world")
    bare, drop = table.loc["bare"], table.loc["drop"]
    assert bare["us_per_step"] == pytest.approx(11.0)  # (100 + 120) / 2 calls / 10 substeps
    assert bare["us_per_step_low"] == pytest.approx(11.0)  # both repeats equal: no spread
    assert bare["mean_contact_points"] == 4.0 and math.isnan(bare["us_per_contact_point"])
    assert math.isnan(bare["bullet_share"]) and bare["repeats"] == 2 and bare["calls"] == 4
    # drops: repeat 0 30 us, repeat 1 30 us per internal step; with Python 40 and 37.5
    assert drop["us_per_step"] == pytest.approx(30.0)
    assert drop["us_per_step_all"] == pytest.approx(38.75)
    half = 12.706204736174707 * 1.25  # t(0.975, 1) * sd(40, 37.5) = 2.5 / sqrt(2), / sqrt(2)
    assert (drop["us_per_step_all_low"], drop["us_per_step_all_high"]) == pytest.approx((38.75 - half, 38.75 + half))
    assert drop["bullet_share"] == pytest.approx(1.2e-3 / 1.55e-3)
    # per internal step 20, 40, 30, 30 us at 4, 8, 6, 6 points: 5 us per point, 0 at none
    assert (drop["us_at_no_contact"], drop["us_per_contact_point"]) == pytest.approx((0.0, 5.0), abs=1e-9)


def test_a_real_drop_times_every_step_and_counts_its_contacts():
    geom = load_part(str(ROOT / "parts" / "rect-a2.stl"))
    cpu, calls, timed = step.drop_steps(
        geom, parse_location("straight:30"), parse_location("none"), np.array([10.0]), SCENE, FAST
    )
    assert len(timed) == calls > 10 and cpu > 0
    assert all(c >= 0 for c, _ in timed)
    points = np.array([n for _, n in timed])
    assert points.min() >= 0 and points.max() > 4  # on the belt (4) and against the fence at some point
    assert sum(c for c, _ in timed) < cpu * 2  # Bullet's share of a like run, not some other clock


def test_the_bare_world_is_a_box_at_rest_on_its_four_corners():
    geom = load_part(str(ROOT / "parts" / "hex-a.stl"))
    calls = step.bare_steps(geom, SCENE, FAST, yaw_deg=30.0, calls=5, settle=5)
    assert len(calls) == 5 and all(n == 4 for _, n in calls) and all(c > 0 for c, _ in calls)


def test_a_configuration_with_no_fence_in_reach_is_refused():
    geom = load_part(str(ROOT / "parts" / "rect-a2.stl"))
    with pytest.raises(FeederError, match="no fence in reach"):
        step.drop_steps(geom, parse_location("none"), parse_location("none"), np.array([0.0]), SCENE, FAST)


def test_cli_refuses_a_configuration_that_is_not_loc1_loc2(tmp_path, capsys):
    import json

    from feeder.cli import main

    bench = dict(CONFIG["sim"]["step_bench"], configurations=["straight:30"])
    settings = {"scene": SCENE, "sim": dict(CONFIG["sim"], step_bench=bench), "parts": {"dir": str(ROOT / "parts")}}
    out = tmp_path / "t.csv"
    code = main(
        ["bench-step", "--settings", json.dumps(settings), "--out-csv", str(out), "--out-raw", str(tmp_path / "r.csv")]
    )
    err = capsys.readouterr().err.strip()
    assert code == 2 and "LOC1|LOC2" in err and "\n" not in err and not out.exists()
