"""Physics of the simulated scene against theory, shortcut proofs and the hard-case suite.

Theory (quasi-static pushing; Goldberg's radius function; Mason / Peshkin & Sanderson): a part
pushed by a long fence turns until an edge lies flush; with a uniform initial yaw the long edge of
a 2:1 rectangle ends flush with probability 2·atan(2)/π; a fence whose normal makes β with the
belt velocity holds parts unless tan β > μ_fence. Every shortcut of the fast preset, and lanes,
is compared drop by drop with the simulation without it, on the same initial yaws
(:func:`feeder.bench.designs.paired_basins`): pooled distributions hide a drop that flips basin
while another flips back.
"""

import copy
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from feeder.bench.accuracy import bootstrap_js_floor
from feeder.bench.designs import paired_basins
from feeder.labels import metrics as labels
from feeder.lane.fences import parse_location
from feeder.lane.geometry import fence_tip
from feeder.parts.shapes import mirror_part, mod180_dist, shape_part
from feeder.sim import body as simbody
from feeder.sim import drops as sim
from feeder.sim.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]
CFG = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
SCENE, PRESETS = CFG["scene"], CFG["sim"]["presets"]
FAST = PRESETS["fast"]
BINS, SIGMA = CFG["labels"]["bins"], CFG["labels"]["sigma_bins"]
V = SCENE["belt"]["speed"]
# Shortcut proofs compare a shortcut with the full simulation at the same physics settings; to keep
# them fast they run at 1.67 ms internal steps (the shortcuts do not depend on the step size).
PROOF = dict(FAST, substeps=3)
FULL = dict(PROOF, lanes=1, full_path=True, skip_slides=False)


def _pmf(yaws):
    y = np.asarray(yaws)
    return labels.pmf_from_yaws(y[np.isfinite(y)], BINS, SIGMA)


def _js(a, b):
    return float(labels.js_divergence(_pmf(a), _pmf(b)))


def _w1(a, b):
    return float(labels.w1(labels.cdf(_pmf(a)), labels.cdf(_pmf(b))))


def _floor(a, b):
    """Noise floor of JS at this drop count: 95 % of bootstrap values from the two pooled runs,
    never below the two-seed value itself."""
    boot = bootstrap_js_floor(a, b, len(a), BINS, SIGMA, 200, 0.95, seed=0)
    return max(boot, _js(a, b))


def _sim(shape, loc1, loc2, drops, seed=0, preset=FAST, scene=SCENE, **kw):
    geom = shape if not isinstance(shape, str) else shape_part(shape, 0.005)
    return simulate(geom, parse_location(loc1), parse_location(loc2), drops, seed, scene, preset, **kw)


# ------------------------------------------------------------------------------------------
# theory
# ------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_two_to_one_rectangle_long_edge_flush_probability():
    """Measured while the part is pushed along a long 45° fence (before the exit turn)."""
    scene = copy.deepcopy(SCENE)
    scene["fences"]["straight"]["tip_past_centre"] = 0.2  # a long fence: the part settles flush
    res = _sim("rect-40x20", "straight:45", "none", 200, scene=scene, probe_x=-0.1)
    yaw = res["diag"]["probe_yaw"]
    assert np.isfinite(yaw).all()
    fence_dir = 135.0  # Location 1 (right side) at 45°: the fence runs along 135°
    long_flush = mod180_dist(yaw, fence_dir) < 10.0
    short_flush = mod180_dist(yaw, fence_dir - 90.0) < 10.0
    assert (long_flush | short_flush).all()  # every part lies flush with one edge
    assert long_flush.mean() == pytest.approx(2 * math.atan(2) / math.pi, abs=0.05)


def test_fence_jams_below_friction_angle_and_passes_above():
    # straight fence at θ from the travel direction: β (velocity vs fence normal) = 90° - θ
    jam = _sim("rect-40x20", "straight:75", "none", 12)  # β = 15°: tan 15° < μ = 0.5
    assert set(jam["status"]) == {"jammed"}
    ok = _sim("rect-40x20", "straight:45", "none", 12)  # β = 45°: tan 45° > 0.5
    assert set(ok["status"]) == {"ok"}
    assert ok["diag"]["final_x"].max() < -0.06  # every part left the fence past its tip


@pytest.mark.slow
def test_mirrored_scene_and_part_give_the_mirrored_distribution():
    tri = shape_part("tri-40x25", 0.005)
    r0 = _sim(tri, "straight:30", "none", 100, seed=0)
    base0, base1 = r0["final_yaw_deg"], _sim(tri, "straight:30", "none", 100, seed=1)["final_yaw_deg"]
    mscene = copy.deepcopy(SCENE)
    mscene["mirror"] = True
    # the same drops mirrored: initial yaw ψ becomes -ψ for the mirrored part
    mirr = sim.run_drops(
        mirror_part(tri),
        parse_location("straight:30"),
        parse_location("none"),
        np.mod(-r0["initial_yaw_deg"], 360.0),
        mscene,
        FAST,
    )["final_yaw_deg"]
    unmirrored = np.mod(-mirr, 360.0)  # the mirror image of yaw ψ is -ψ
    floor = _floor(base1, base0)
    assert _js(unmirrored, base0) < floor
    assert _js(mirr, base0) > floor  # not mirroring back is visibly different: the test can fail


@pytest.mark.slow
def test_three_to_one_rectangle_concentrates_after_a_long_fence():
    res = _sim("rect-60x20", "straight:30", "none", 60)
    y = res["final_yaw_deg"][res["status"] == "ok"]
    assert y.size >= 55
    hist = np.histogram(np.mod(y, 180.0), bins=36, range=(0, 180))[0]
    mode = (np.argmax(hist) + 0.5) * 5.0
    assert np.mean(mod180_dist(y, mode) < 15.0) > 0.8


@pytest.mark.slow
@pytest.mark.parametrize(
    "shape, loc1, loc2", [("rect-40x20", "straight:45", "none"), ("tri-40x25", "curved:30", "none")]
)
def test_halving_the_time_step_moves_the_pmf_less_than_the_noise_floor(shape, loc1, loc2):
    half = dict(FAST, substeps=2 * FAST["substeps"])
    a0 = _sim(shape, loc1, loc2, 40, seed=0)["final_yaw_deg"]
    a1 = _sim(shape, loc1, loc2, 40, seed=1)["final_yaw_deg"]
    h0 = _sim(shape, loc1, loc2, 40, seed=0, preset=half)["final_yaw_deg"]
    assert _w1(h0, a0) < _w1(a1, a0)


# ------------------------------------------------------------------------------------------
# shortcuts and lanes against the simulation without them, drop by drop (same initial yaws)
# ------------------------------------------------------------------------------------------
SCENES = [
    ("rect-40x20", "straight:45", "none"),
    ("tri-40x25", "curved:30", "none"),
    ("l-40x30x10", "straight:30", "straight:45"),
]
SHORTCUT_DROPS = 50
# a shorter belt for the full path (start 0.2 m before Location 2, record just past the fences)
SHORT_BELT = copy.deepcopy(SCENE)
SHORT_BELT["belt"].update(start_y=0.3, end_y=0.0, end_margin=0.1)
# The lanes' proofs run on the pieces contact, on which they were measured. Under 16 footprint pads 2
# lanes move the rect's drops by a median -0.49 deg against 1 lane (same basin 1.0; measured
# 2026-11-25): lanes > 1 are not for the pads (docs/simulation.md); every preset keeps lanes 1.
PIECES_BELT = copy.deepcopy(SHORT_BELT)
PIECES_BELT["belt"]["footprint"] = dict(PIECES_BELT["belt"]["footprint"], model="pieces")
PIECES_BELT["part"]["wall_contact"] = dict(PIECES_BELT["part"]["wall_contact"], model="pieces")
# Goals of issues #19/#23 for a pair of runs of the same 50 drops: at most 1 of 50 drops in another
# basin, median |Δ final yaw| of the rest at most 0.3°. Measured (docs/testing.md, "Paired shortcut
# checks (measured)"): every case below meets them; the closest are 25 lanes on the L (0.98: one
# drop 85° away) and a median of 0.24° (all shortcuts on the L). The full simulation's own floor
# (started 0.1 m earlier, or initial yaws moved by 0.01°): same basin 1.0, median 0.08–0.22°.
SAME_BASIN_GOAL = 0.98
MEDIAN_DYAW_GOAL_DEG = 0.3
# ... and no systematic turn: |median signed Δ| at most 0.15°. Measured on every case below: at
# most 0.115° (slide skipping on the rect), 0.06° or less on the others. A slide skip that lands
# 1 cm past the tip instead of before it turns the L's drops by +0.21° (docs/testing.md).
SIGNED_SHIFT_GOAL_DEG = 0.15
# the settings compared: (name, overrides of PROOF, overrides of PROOF for its baseline)
SHORTCUTS = [
    ("all shortcuts (fast)", {}, FULL),
    ("lanes only", {"lanes": 25, "full_path": True, "skip_slides": False}, FULL),
    ("start/teleport/stop only", {"lanes": 1, "skip_slides": False}, FULL),
    # the slide skip acts only without the full path (drops.Limits), so it is isolated against the
    # same start/teleport/stop shortcuts without it (against FULL it would repeat the fast case)
    ("slide skipping only", {"lanes": 1, "full_path": False, "skip_slides": True}, {"skip_slides": False}),
]
_RUNS = {}


def _run(scene_key, preset, scene=None):
    """One run of SHORTCUT_DROPS drops (seed 0) on the short belt (or ``scene``), cached per test module."""
    scene = SHORT_BELT if scene is None else scene
    key = (scene_key, json.dumps(preset, sort_keys=True), json.dumps(scene, sort_keys=True))
    if key not in _RUNS:
        _RUNS[key] = _sim(*scene_key, SHORTCUT_DROPS, seed=0, preset=preset, scene=scene)
    return _RUNS[key]


def _paired(run, baseline, what):
    """``paired_basins`` of two runs of the same drops, and a message with its numbers."""
    assert np.array_equal(run["initial_yaw_deg"], baseline["initial_yaw_deg"])  # the same drops
    c = paired_basins(run["final_yaw_deg"], run["status"], baseline["final_yaw_deg"], baseline["status"])
    return c, (
        f"{what}: same basin {c['same_basin']:.3f} (goal >= {SAME_BASIN_GOAL}), median |dyaw| "
        f"{c['median_dyaw_deg']:.3f} deg (goal <= {MEDIAN_DYAW_GOAL_DEG}), median signed dyaw "
        f"{c['median_signed_dyaw_deg']:+.3f} deg (goal within +-{SIGNED_SHIFT_GOAL_DEG}), "
        f"max {c['max_dyaw_deg']:.3f} deg, n {c['n']}"
    )


def _meets_goals(c) -> bool:
    return (
        c["same_basin"] >= SAME_BASIN_GOAL
        and c["median_dyaw_deg"] <= MEDIAN_DYAW_GOAL_DEG
        and abs(c["median_signed_dyaw_deg"]) <= SIGNED_SHIFT_GOAL_DEG
    )


# Known misses since the round fence tip became the default (2026-11-29, stop 65; measured on this
# scene, the goals above unchanged): on the L the start/teleport/stop shortcuts turn every drop by
# about -0.24 deg (same basin 1.0, median |dyaw| 0.24-0.25 deg, median signed -0.24 to -0.25 deg:
# a systematic turn beyond SIGNED_SHIFT_GOAL_DEG), and 25 lanes put 2 of 50 drops in another basin
# (0.96, median signed -0.01 deg; no preset runs lanes > 1). Under the square tip all three met the
# goals. Narrowed at stop 66 to the shortcut start (docs/testing.md, "Where the turn comes from").
# Strict: a fix that meets the goals again fails these marks and must remove them.
ROUND_TIP_MISSES = {
    ("all shortcuts (fast)", ("l-40x30x10", "straight:30", "straight:45")): "fast: median signed dyaw -0.238 deg",
    ("start/teleport/stop only", ("l-40x30x10", "straight:30", "straight:45")): "median signed dyaw -0.250 deg",
    ("lanes only", ("l-40x30x10", "straight:30", "straight:45")): "25 lanes: same basin 0.96",
}


@pytest.mark.slow
@pytest.mark.parametrize("scene_key", SCENES, ids=lambda s: "_".join(s))
@pytest.mark.parametrize("name, overrides, baseline", SHORTCUTS, ids=[s[0] for s in SHORTCUTS])
def test_shortcut_matches_full_simulation(scene_key, name, overrides, baseline, request):
    miss = ROUND_TIP_MISSES.get((name, tuple(scene_key)))
    if miss and fence_tip(SCENE) == "round":
        request.applymarker(pytest.mark.xfail(strict=True, reason=f"round fence tip (issue #39): {miss}"))
    scene = PIECES_BELT if overrides.get("lanes", 1) > 1 else SHORT_BELT
    run = _run(scene_key, dict(PROOF, **overrides), scene)
    base = _run(scene_key, dict(PROOF, **baseline), scene)
    c, msg = _paired(run, base, f"{name} on {scene_key}")
    assert c["n"] == SHORTCUT_DROPS, msg
    assert _meets_goals(c), msg


@pytest.mark.slow
@pytest.mark.parametrize("scene_key", SCENES, ids=lambda s: "_".join(s))
def test_two_lanes_give_the_drops_of_one_lane(scene_key):
    """Lanes > 1 must leave each drop where one lane puts it (issue #23): the fast shortcuts with
    2 lanes against 1, the same drops. Measured: same basin 1.0, median 0.13–0.23° (lanes 4:
    1.0, 0.12–0.29°), within the full simulation's own floor."""
    two = _run(scene_key, dict(PROOF, lanes=2), PIECES_BELT)
    one = _run(scene_key, dict(PROOF, lanes=1), PIECES_BELT)
    c, msg = _paired(two, one, f"2 lanes against 1 on {scene_key}")
    assert _meets_goals(c), msg


# ------------------------------------------------------------------------------------------
# hard cases: stable, no tunnelling, no energy gain, status counts written
# ------------------------------------------------------------------------------------------
HARD = [
    ("rect-80x8", "straight:40", "none"),  # thin, aspect 10
    ("rect-10x8", "straight:30", "none"),  # small
    ("c-40x30x8", "straight:45", "none"),  # concave C
    ("star-5x25x10", "straight:30", "curved:45"),  # concave star
    ("ellipse-16x15", "straight:30", "none"),  # near-circular
    ("rect-120x60", "straight:5", "none"),  # angles near the ends of their ranges
    ("rect-40x20", "straight:89", "none"),
    ("rect-100x50", "curved:0", "curved:90"),
    ("tri-40x25", "curved:60", "curved:30"),  # curved + curved
    ("washer-25x8", "straight:30", "curved:45"),  # through-holes: a ring
    ("plate-60x30x10", "straight:40", "none"),  # a bolt hole off the middle: mass off the outline's centroid
]


PADS = dict(model="pads", pads=16, pad_radius=0.001)
# the hard cases again on footprint pads (scene.belt.footprint), with the library's thinnest part
HARD_PADS = [
    case
    for case in HARD
    if case[0] in ("rect-80x8", "rect-10x8", "c-40x30x8", "star-5x25x10", "tri-40x25", "washer-25x8", "plate-60x30x10")
]


@pytest.mark.parametrize("shape, loc1, loc2", HARD)
def test_hard_case_is_stable(shape, loc1, loc2):
    _check_hard_case(shape_part(shape, 0.005), loc1, loc2, SCENE)


@pytest.mark.parametrize("shape, loc1, loc2", HARD_PADS + [("crescent-thin", "straight:30", "curved:40")])
def test_hard_case_is_stable_on_footprint_pads(shape, loc1, loc2):
    from feeder.parts.geometry import load_part

    scene = copy.deepcopy(SCENE)
    scene["belt"]["footprint"] = PADS
    geom = load_part(ROOT / "parts" / f"{shape}.stl") if shape == "crescent-thin" else shape_part(shape, 0.005)
    res = _check_hard_case(geom, loc1, loc2, scene)
    assert "flipped" not in set(res["status"])  # pads hold only the bottom: no part tips over


def _check_hard_case(geom, loc1, loc2, scene):
    res = _sim(geom, loc1, loc2, 10, scene=scene, check_fences=True)
    d = res["diag"]
    status = res["status"]
    assert "nan" not in set(status)
    assert set(status) <= set(sim.STATUSES)
    assert not d["inside_fence"].any()  # the centroid never entered a fence: no tunnelling
    # no energy gain: never faster than the belt by more than a quarter (world frame), and the
    # kinetic energy never beyond twice the energy of riding the belt
    model = simbody.part_model(geom, scene)
    assert d["max_speed"].max() <= 1.25 * V
    energy = 0.5 * model.mass * d["max_speed"] ** 2 + 0.5 * model.inertia[2] * d["max_omega"] ** 2
    assert energy.max() <= 2.0 * 0.5 * model.mass * V**2
    ok = status == "ok"
    assert np.isfinite(res["final_yaw_deg"][ok]).all() and np.isnan(res["final_yaw_deg"][~ok]).all()
    counts = json.loads(res["meta"])["status_counts"]
    assert sum(counts.values()) == 10 and counts["ok"] == ok.sum()
    # a part that went past a Location 1 straight fence ends on its inner side (not behind it)
    if loc1.startswith("straight") and loc2 == "none" and ok.any() and d["plan_fences"]:
        (box,) = sim.make_plan(scene, parse_location(loc1), parse_location(loc2), model, False).fences[0].boxes
        cx, cy, hl, ht, yaw = box
        tip_x = cx + hl * math.cos(yaw)
        assert (d["final_x"][ok] < tip_x + model.radius).all()
    return res
