"""feeder.sim.drops / body / scene / record: pure math against hand values, the CLI, determinism, the body model."""

import copy
import json
import math
import subprocess
import sys
from collections import deque
from pathlib import Path

import numpy as np
import pytest
import yaml

from feeder.errors import FeederError
from feeder.lane import geometry as lane_geometry
from feeder.lane.fences import Fence, parse_location
from feeder.lane.settings import load_settings
from feeder.parts.geometry import PartGeometry, load_part, stl_bytes
from feeder.parts.shapes import shape_part
from feeder.sim import body as simbody
from feeder.sim import drops as sim
from feeder.sim import record
from feeder.sim import scene as sc
from feeder.sim.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]
CFG = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
DEFAULT_SCENE = copy.deepcopy(CFG["scene"])  # config/config.yaml's own
# the pieces contact (config/pieces.yaml), which these tests were written for; the default's (pads and
# outline slabs) is pinned in tests/test_sim_pinned.py and covered by tests/test_outline_contact.py
CFG["scene"]["belt"]["footprint"]["model"] = "pieces"
CFG["scene"]["part"]["wall_contact"]["model"] = "pieces"
SCENE, PRESETS = CFG["scene"], CFG["sim"]["presets"]
FAST = PRESETS["fast"]
RECT = PartGeometry.from_polygon("rect", [(0, 0), (0.04, 0), (0.04, 0.02), (0, 0.02)], 0.005)


def run(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "feeder", *args], cwd=cwd, capture_output=True, text=True)


# ------------------------------------------------------------------------------------------
# pure functions
# ------------------------------------------------------------------------------------------
def test_principal_inertia_rectangle_hand_values():
    # 40 x 20 mm, 5 mm, 1200 kg/m³: m = 1200·0.005·8e-4; ∫x² = w³h/12, ∫y² = wh³/12
    m, (ixx, iyy, izz), alpha = simbody.principal_inertia(
        8e-4, (0.04 * 0.02**3 / 12, 0.04**3 * 0.02 / 12, 0.0), 0.005, 1200.0
    )
    assert m == pytest.approx(0.0048)
    flat = m * 0.005**2 / 12
    assert ixx == pytest.approx(6.0 * 0.04 * 0.02**3 / 12 + flat)
    assert iyy == pytest.approx(6.0 * 0.04**3 * 0.02 / 12 + flat)
    assert izz == pytest.approx(8.0e-7)
    assert alpha == pytest.approx(0.0)


def test_principal_axes_of_rotated_rectangle():
    a = math.radians(30)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    pts = np.array([(0, 0), (0.04, 0), (0.04, 0.02), (0, 0.02)]) @ rot.T
    g = PartGeometry.from_polygon("r30", pts, 0.005)
    model = simbody.part_model(g, SCENE)
    assert math.degrees(model.alpha) == pytest.approx(30.0, abs=1e-6)
    ref = simbody.part_model(RECT, SCENE)
    assert np.allclose(model.inertia, ref.inertia, rtol=1e-9)
    assert model.radius == pytest.approx(math.hypot(0.02, 0.01))
    # pieces are inset by the collision margin: 40 x 20 becomes 39.8 x 19.8 mm
    piece = ref.pieces[0]
    assert np.ptp(piece[:, 0]) == pytest.approx(0.04 - 2e-4) and np.ptp(piece[:, 1]) == pytest.approx(0.02 - 2e-4)


def test_seeds_stable_and_distinct():
    s = sim.drop_seed("rect", "straight30_none", 0)
    assert s == sim.drop_seed("rect", "straight30_none", 0)
    assert (
        len(
            {
                s,
                sim.drop_seed("rect", "straight30_none", 1),
                sim.drop_seed("rect", "straight31_none", 0),
                sim.drop_seed("rectb", "straight30_none", 0),
            }
        )
        == 4
    )
    y = sim.initial_yaws(s, 500)
    assert np.array_equal(y, sim.initial_yaws(s, 500)) and y.min() >= 0 and y.max() < 360
    assert np.array_equal(sim.initial_yaws(s, 100), y[:100])  # drop order: a prefix is a prefix


def test_golden_yaws_spread_every_prefix_evenly():
    s = sim.drop_seed("rect", "straight30_none", 0)
    g = sim.initial_yaws(s, 1000, "golden")
    assert np.array_equal(g, sim.initial_yaws(s, 1000, "golden")) and g.min() >= 0 and g.max() < 360
    assert np.array_equal(sim.initial_yaws(s, 50, "golden"), g[:50])
    assert not np.array_equal(g[:10], sim.initial_yaws(s, 10))  # another design than random
    # consecutive drops 360/phi apart (mod 360)
    assert np.allclose(np.mod(np.diff(g), 360.0), 360.0 * (math.sqrt(5) - 1) / 2)
    r = sim.initial_yaws(s, 1000)

    def ks(y):  # KS distance of a sample of yaws to the uniform distribution on [0, 360)
        return np.max(np.abs(np.sort(y) / 360.0 - (np.arange(len(y)) + 0.5) / len(y)))

    for n in (10, 37, 100, 1000):
        ys = np.sort(g[:n])
        gaps = np.diff(np.r_[ys, ys[0] + 360.0])
        # three-gap theorem: at most three distinct gaps, the largest under 2.7 x the mean
        assert len(np.unique(np.round(gaps, 6))) <= 3 and gaps.max() < 2.7 * 360.0 / n
        # every prefix is closer to uniform (KS distance) than independent draws of the same size
        assert ks(g[:n]) < ks(r[:n]) and ks(g[:n]) < 2.0 / n
    with pytest.raises(FeederError, match="initial yaws are drawn for"):
        sim.initial_yaws(s, 5, "sobol")
    with pytest.raises(FeederError, match="initial yaws are drawn for"):
        sim.initial_yaws(s, 5, "adaptive")  # chooses its yaws as it goes


def test_grid_yaws_are_evenly_spaced_with_a_seeded_offset():
    s = sim.drop_seed("rect-a", "straight30_none", 0)
    g = sim.initial_yaws(s, 8, "grid")
    np.testing.assert_allclose(np.diff(g), 45.0)
    assert 0.0 <= g[0] < 45.0 and np.array_equal(g, sim.initial_yaws(s, 8, "grid"))
    assert sim.initial_yaws(sim.drop_seed("rect-a", "straight30_none", 1), 8, "grid")[0] != g[0]


def test_straight_fence_geometry_hand_values():
    (box,) = lane_geometry.fence_geometry(SCENE, "loc1", Fence("straight", 30.0)).boxes
    cx, cy, hl, ht, yaw = box
    d = np.array([math.cos(yaw), math.sin(yaw)])
    tip = np.array([cx, cy]) + hl * d
    assert tip == pytest.approx([-0.06, 1.0 + 0.30 / math.tan(math.radians(30))])  # 0.06 past the centre
    assert math.degrees(yaw) == pytest.approx(120.0)  # 30° from +y, inward (towards -x)
    assert ht == pytest.approx(0.005)
    # the slot point (0.24, 1.0) lies on the centre line
    rel = np.array([0.24, 1.0]) - np.array([cx, cy])
    assert abs(rel[0] * -d[1] + rel[1] * d[0]) < 1e-12
    # Location 2 is the mirror image on the left, at y = 0.5
    (b2,) = lane_geometry.fence_geometry(SCENE, "loc2", Fence("straight", 30.0)).boxes
    assert b2[0] == pytest.approx(-cx) and b2[1] == pytest.approx(cy - 0.5)
    mirrored = copy.deepcopy(SCENE)
    mirrored["mirror"] = True
    (bm,) = lane_geometry.fence_geometry(mirrored, "loc1", Fence("straight", 30.0)).boxes
    assert bm[0] == pytest.approx(-cx) and bm[1] == pytest.approx(cy)


def test_crossing_fences_are_trimmed_to_the_least_gap():
    """Upstream 15° (1.16 m to the centre line) and downstream 30° cross without trimming: a V that
    traps every part. The upstream fence keeps its wall end and loses length until the gap holds;
    pairs that never come close are untouched."""
    gap = SCENE["fences"]["min_gap"]
    up_full = lane_geometry.fence_geometry(SCENE, "loc2", Fence("straight", 15.0))
    down = lane_geometry.fence_geometry(SCENE, "loc1", Fence("straight", 30.0))
    assert up_full.footprint().intersects(down.footprint())  # the untrimmed pair crosses
    up, down2 = lane_geometry.scene_fences(SCENE, Fence("straight", 30.0), Fence("straight", 15.0))
    assert down2.boxes == down.boxes
    dist = up.footprint().distance(down.footprint())
    assert gap <= dist < gap + 1e-3  # trimmed just enough (bisection tolerance)
    cx, cy, hl, _, yaw = up.boxes[0]
    fx, fy, fhl, _, fyaw = up_full.boxes[0]
    assert yaw == fyaw and hl < fhl
    wall_end = np.array([cx, cy]) - hl * np.array([math.cos(yaw), math.sin(yaw)])
    assert wall_end == pytest.approx(np.array([fx, fy]) - fhl * np.array([math.cos(fyaw), math.sin(fyaw)]))
    # far apart: unchanged; every pair of the grid keeps the gap
    up45, _ = lane_geometry.scene_fences(SCENE, Fence("straight", 30.0), Fence("straight", 45.0))
    assert up45.boxes == lane_geometry.fence_geometry(SCENE, "loc2", Fence("straight", 45.0)).boxes
    grid = [Fence("straight", a) for a in CFG["fences"]["straight_angles"]] + [
        Fence("curved", a) for a in CFG["fences"]["curved_angles"]
    ]
    for f1 in grid:
        for f2 in grid:
            fences = lane_geometry.scene_fences(SCENE, f1, f2)
            if len(fences) == 2:
                assert fences[0].footprint().distance(fences[1].footprint()) >= gap - 1e-9


def test_trimmed_curved_fence_loses_tip_boxes():
    scene = copy.deepcopy(SCENE)
    scene["fences"]["min_gap"] = 0.6  # forces trimming of a curved upstream fence
    up_full = lane_geometry.fence_geometry(scene, "loc2", Fence("curved", 30.0))
    down = lane_geometry.fence_geometry(scene, "loc1", Fence("straight", 30.0))
    trimmed = lane_geometry.trim_to_gap(up_full, down, 0.6)
    assert 0 < len(trimmed.boxes) < len(up_full.boxes)
    assert trimmed.boxes == up_full.boxes[: len(trimmed.boxes)]  # from the tip: the slot end stays
    assert trimmed.footprint().distance(down.footprint()) >= 0.6


@pytest.mark.parametrize("theta", [0.0, 30.0, 90.0])
def test_curved_fence_centre_and_outer_face(theta):
    pts, centre = lane_geometry.curved_polyline(theta, 1, 0.24, 1.0, 0.2, 90.0, 16)
    th = math.radians(theta)
    assert centre == pytest.approx([0.24 - 0.2 * math.sin(th), 1.0 + 0.2 * math.cos(th)])  # paper formula
    assert pts[0] == pytest.approx([0.24, 1.0])  # the arc starts at the slot
    assert np.allclose(np.hypot(*(pts - centre).T), 0.2)
    assert np.all(np.diff(pts[:, 0]) < 0)  # runs inward
    boxes = lane_geometry.fence_geometry(SCENE, "loc1", Fence("curved", theta)).boxes
    assert len(boxes) == 16
    # outer faces: every box's outer mid-face lies on the circle r + t/2 within the sagitta
    for cx, cy, _, ht, yaw in boxes:
        n = np.array([math.sin(yaw), -math.cos(yaw)])
        if np.dot(np.array([cx, cy]) - centre, n) < 0:
            n = -n
        face = np.array([cx, cy]) + ht * n
        assert np.hypot(*(face - centre)) == pytest.approx(0.205, abs=3e-4)


def test_gap_ahead_hand_values():
    square = np.array([(-0.01, -0.01), (0.01, -0.01), (0.01, 0.01), (-0.01, 0.01)])
    pts = np.array([(0.0, 0.05), (0.005, 0.03), (0.5, 0.0), (0.0, -0.2)])
    assert sim.gap_ahead(square, pts, 0.0) == pytest.approx(0.02)  # (0.005, 0.03) - top 0.01
    assert sim.gap_ahead(square, pts[[2, 3]], 0.0) is None  # beside and behind: clear
    assert sim.gap_ahead(square, np.array([(0.0115, 0.02)]), 0.002) == pytest.approx(0.01)  # padded in x
    tri = np.array([(-0.01, 0.0), (0.01, 0.0), (0.0, 0.01)])
    assert sim.gap_ahead(tri, np.array([(0.005, 0.02)]), 0.0) == pytest.approx(0.015)


def test_quaternion_helpers():
    q = [0.0, 0.0, math.sin(0.35), math.cos(0.35)]
    assert simbody.quat_yaw(q) == pytest.approx(0.7)
    assert simbody.quat_tilt_deg(q) == pytest.approx(0.0, abs=1e-9)
    qx = [math.sin(math.radians(20)), 0.0, 0.0, math.cos(math.radians(20))]
    assert simbody.quat_tilt_deg(qx) == pytest.approx(40.0)


def test_table1_lists_the_scene_from_config(tmp_path):
    out = tmp_path / "t1.csv"
    settings = json.dumps({"scene": SCENE, "sim": CFG["sim"]})
    r = run("scene-table", "--settings", settings, "--out", str(out))
    assert r.returncode == 0, r.stderr
    text = out.read_text()
    for needle in [
        "Conveyor speed,0.1",
        "Part friction (Coulomb mu),0.8",
        "Fence friction (Coulomb mu),0.5",
        "Belt friction (Coulomb mu),1",
        "Restitution,0",
        "r = 0.2",
        "+-0.24 / +-0.272",
    ]:
        assert needle in text
    changed = copy.deepcopy(SCENE)
    changed["part"]["density"] = 777.0
    run("scene-table", "--settings", json.dumps({"scene": changed, "sim": CFG["sim"]}), "--out", str(out))
    assert "Part density,777" in out.read_text()


def test_load_settings_from_a_settings_json_in_either_form():
    assert load_settings(json.dumps({"scene": SCENE, "presets": PRESETS})) == (SCENE, PRESETS)
    assert load_settings(json.dumps({"scene": SCENE, "sim": CFG["sim"]})) == (SCENE, PRESETS)
    with pytest.raises(FeederError, match="lack the 'scene' section"):
        load_settings(json.dumps({"presets": PRESETS}))
    with pytest.raises(FeederError, match="simulation presets"):
        load_settings(json.dumps({"scene": SCENE}))
    with pytest.raises(FeederError, match="not valid JSON"):
        load_settings("{scene")


def test_load_settings_without_json_reads_the_study_config_of_root_or_cwd(tmp_path, monkeypatch):
    """The study config via feeder.config.load_study_config: that of ``root``, else of the working
    directory when it has one, else the repository's (so a command works from any directory)."""
    study = tmp_path / "study"
    (study / "config").mkdir(parents=True)
    scene = copy.deepcopy(SCENE)
    scene["gravity"] = -1.5
    (study / "config" / "config.yaml").write_text(yaml.safe_dump({"scene": scene, "sim": {"presets": {"fast": FAST}}}))
    assert load_settings(root=study) == (scene, {"fast": FAST})
    monkeypatch.chdir(study)
    assert load_settings() == (scene, {"fast": FAST})
    monkeypatch.chdir(tmp_path)  # no config here: the repository's
    assert load_settings() == (DEFAULT_SCENE, PRESETS)


def test_load_settings_without_a_config_is_a_one_line_error(tmp_path):
    with pytest.raises(FeederError) as err:
        load_settings(root=tmp_path)
    message = str(err.value)
    assert "\n" not in message
    assert str(tmp_path / "config" / "config.yaml") in message and "--settings" in message


def test_table1_without_settings_runs_outside_the_project_root(tmp_path):
    out = tmp_path / "t1.csv"
    r = run("scene-table", "--out", str(out), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "Conveyor speed,0.1" in out.read_text()


# ------------------------------------------------------------------------------------------
# simulation: no fences, determinism, the CLI
# ------------------------------------------------------------------------------------------
def test_no_fences_final_equals_initial_without_physics():
    res = simulate(RECT, Fence("none"), Fence("none"), 300, 0, SCENE, FAST)
    assert np.array_equal(res["final_yaw_deg"], res["initial_yaw_deg"])
    assert set(res["status"]) == {"ok"}
    assert res["diag"]["plan_fences"] == []


def test_unreachable_fence_is_not_built_and_changes_nothing():
    small = shape_part("rect-20x10", 0.005)
    # a curved fence at 0° ends 0.04 m from the centre line: a part of radius 11 mm never meets it
    res = simulate(small, Fence("curved", 0.0), Fence("none"), 6, 0, SCENE, FAST)
    assert res["diag"]["plan_fences"] == []
    full = simulate(small, Fence("curved", 0.0), Fence("none"), 6, 0, SCENE, FAST, prune=False)
    assert full["diag"]["plan_fences"] == ["loc1"]
    assert set(full["status"]) == {"ok"}
    d = np.abs((full["final_yaw_deg"] - res["final_yaw_deg"] + 180) % 360 - 180)
    assert d.max() < 0.5  # built and simulated, the fence does nothing (rest creep only)


def _stl(tmp_path, name, outline, thickness=0.005):
    path = tmp_path / f"{name}.stl"
    path.write_bytes(stl_bytes(np.asarray(outline, float), thickness))
    return path


def test_cli_writes_npz_per_contract_and_reruns_bit_identical(tmp_path):
    part = _stl(tmp_path, "rect", [(0, 0), (0.04, 0), (0.04, 0.02), (0, 0.02)])
    settings = json.dumps({"scene": SCENE, "presets": PRESETS})
    outs = []
    for k in range(2):
        out = tmp_path / f"o{k}.npz"
        r = run(
            "simulate",
            "--part",
            str(part),
            "--loc1",
            "straight:45",
            "--loc2",
            "none",
            "--drops",
            "8",
            "--seed",
            "3",
            "--preset",
            "fast",
            "--settings",
            settings,
            "--out",
            str(out),
        )
        assert r.returncode == 0, r.stderr
        outs.append(np.load(out))
    a, b = outs
    assert set(a.files) == {"final_yaw_deg", "initial_yaw_deg", "status", "wall_s", "cpu_s", "meta"}
    assert a["final_yaw_deg"].dtype == np.float64 and a["final_yaw_deg"].shape == (8,)
    assert a["status"].dtype.kind == "U" and a["wall_s"].shape == () and a["cpu_s"].shape == ()
    meta = json.loads(str(a["meta"]))
    assert (meta["part"], meta["loc1"], meta["loc2"], meta["preset"], meta["seed"], meta["drops"]) == (
        "rect",
        "straight:45",
        "none",
        "fast",
        3,
        8,
    )
    assert "scene" in meta["settings"] and sum(meta["status_counts"].values()) == 8
    ok = a["status"] == "ok"
    assert np.all(np.isnan(a["final_yaw_deg"][~ok]))
    assert np.all((a["final_yaw_deg"][ok] >= 0) & (a["final_yaw_deg"][ok] < 360))
    for key in ("final_yaw_deg", "initial_yaw_deg", "status"):
        assert np.array_equal(a[key], b[key], equal_nan=key != "status")


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--loc1", "straight:90"], "straight fence angle 90"),
        (["--loc1", "curved:-5"], "curved fence angle -5"),
        (["--loc1", "wiggly:30"], "fence type 'wiggly'"),
        (["--drops", "0"], "--drops must be positive"),
        (["--part", "MISSING"], "not found"),
        (["--part", "BROKEN"], "BROKEN"),
        (["--preset", "turbo"], "preset 'turbo'"),
        (["--yaw-sampling", "adaptive", "--stop-if-none-ok", "maybe"], "--stop-if-none-ok must be true or false"),
    ],
)
def test_cli_bad_input_one_line_error_no_output(tmp_path, args, needle):
    good = _stl(tmp_path, "rect", [(0, 0), (0.04, 0), (0.04, 0.02), (0, 0.02)])
    broken = tmp_path / "broken.stl"
    broken.write_bytes(b"solid nothing\nendsolid\n")
    base = {"--part": str(good), "--loc1": "straight:30", "--loc2": "none", "--drops": "5", "--preset": "fast"}
    for k, v in zip(args[::2], args[1::2]):
        base[k] = {"MISSING": str(tmp_path / "nope.stl"), "BROKEN": str(broken)}.get(v, v)
    needle = needle.replace("BROKEN", str(broken))
    out = tmp_path / "out.npz"
    flat = [x for kv in base.items() for x in kv]
    r = run("simulate", *flat, "--settings", json.dumps({"scene": SCENE, "presets": PRESETS}), "--out", str(out))
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert lines[-1].startswith("feeder simulate: error:") and needle in lines[-1]
    assert not out.exists()


# ------------------------------------------------------------------------------------------
# the body in pybullet
# ------------------------------------------------------------------------------------------
def _world(geom, loc1="straight:45", lanes=1, preset=FAST, scene=SCENE):
    """A world of ``lanes`` lanes for ``geom`` behind the fence ``loc1`` (tests/test_footprint.py
    passes its padded scene): ``(world, part model, plan)``."""
    model = simbody.part_model(geom, scene)
    plan = sim.make_plan(scene, parse_location(loc1), parse_location("none"), model, False)
    return simbody.World(scene, preset, plan, lanes, model), model, plan


def test_part_rests_at_true_half_thickness_with_set_mass_and_inertia():
    w, model, plan = _world(RECT)
    try:
        w.reset_belt(0)
        body = w.add_part(0, 0.0, plan.start_y - 0.3, 0.0)  # far upstream of the fence
        for _ in range(200):
            w.step()
        pos, q = w.pb.getBasePositionAndOrientation(body)
        assert abs(pos[2] - 0.0025) < 1e-4  # a 5 mm part within 0.1 mm of its half height
        info = w.pb.getDynamicsInfo(body, -1)
        assert info[0] == pytest.approx(model.mass)
        assert np.allclose(info[2], model.inertia)
        assert info[3] == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)  # centre of mass at the centroid
    finally:
        w.close()


def test_parts_in_one_world_never_touch_each_other():
    w, model, plan = _world(RECT, lanes=2)
    try:
        w.reset_belt(0)
        a = w.add_part(0, 0.0, plan.start_y - 0.3, 0.0)
        b = w.add_part(0, 0.01, plan.start_y - 0.3, 0.0)  # overlapping the first one in the same lane
        for _ in range(100):
            w.step()
        assert w.pb.getContactPoints(a, b) == ()
        pa, _ = w.pb.getBasePositionAndOrientation(a)
        pb_, _ = w.pb.getBasePositionAndOrientation(b)
        assert abs(pa[0] - w.lane_x[0]) < 1e-4 and abs(pb_[0] - w.lane_x[0] - 0.01) < 1e-4
    finally:
        w.close()


def _state(**kw):
    """A part's state at one check: flat at rest on the belt at y = 0.5 unless overridden."""
    base = dict(
        elapsed=1.0,
        x=0.0,
        y=0.5,
        z=0.0025,
        q=(0.0, 0.0, 0.0, 1.0),
        lin=(0.0, 0.1, 0.0),
        ang=(0.0, 0.0, 0.0),
        yaw_rad=0.0,
        yaw_deg=0.0,
    )
    return sim.PartState(**dict(base, **kw))


def test_status_checks_in_their_order():
    lim = sim.drop_limits(SCENE, FAST)
    assert lim.check_steps == 4 and lim.rest_checks == 5 and lim.slide_checks == 15  # 0.02 s checks at 5 ms steps
    lane = lambda: sim._Lane(0, 0, 0.0, deque())  # noqa: E731
    tilted = (math.sin(math.radians(20)), 0.0, 0.0, math.cos(math.radians(20)))  # normal 40 deg off vertical
    assert sim.failure(lane(), _state(q=tilted, z=-1.0), lim, 100.0) == "flipped"  # before fell_off
    assert sim.failure(lane(), _state(z=-1.0), lim, 100.0) == "fell_off"
    assert sim.failure(lane(), _state(x=-0.31), lim, 100.0) == "fell_off"
    assert sim.failure(lane(), _state(elapsed=100.02), lim, 100.0) == "timed_out"
    held = lane()  # a part that does not move: jammed once a whole jam window (0.5 s) has passed
    ends = [sim.failure(held, _state(elapsed=0.02 * k), lim, 100.0) for k in range(27)]
    assert ends[:25] == [None] * 25 and ends[25:] == ["jammed", "jammed"]
    assert len(held.hist) == 26  # the checks within the window
    # at rest: carried with the belt since the previous check; a part that turned is not
    hist = deque([(0.98, 0.0, 0.498, 0.0), (1.0, 0.0, 0.5, 0.0)])
    assert sim.at_rest(hist, _state(), lim)
    assert not sim.at_rest(deque([(0.98, 0.0, 0.498, -0.01), (1.0, 0.0, 0.5, 0.0)]), _state(), lim)
    assert not sim.at_rest(deque([(1.0, 0.0, 0.5, 0.0)]), _state(), lim)  # just moved: nothing to compare


def test_sim_file_round_trip(tmp_path):
    res = simulate(RECT, Fence("none"), Fence("none"), 5, 0, SCENE, FAST)
    path = tmp_path / "sim.npz"
    record.write_sim(path, res)
    with np.load(path) as z:
        assert tuple(z.files) == record.SIM_KEYS  # what docs/data.md lists, without the diagnostics
    rec = record.load_sim(path, min_ok_drops=5)
    assert np.array_equal(rec.yaws, res["final_yaw_deg"]) and rec.ok.all() and rec.meta["drops"] == 5
    with pytest.raises(record.BadData, match="5 ok drops of 5"):
        record.load_sim(path, min_ok_drops=6)
    with pytest.raises(record.BadData, match="missing"):
        record.load_sim(tmp_path / "none.npz")


def test_bad_preset_rejected():
    with pytest.raises(FeederError, match="lacks"):
        sim.get_preset({"x": {"time_step": 0.005}}, "x")
    with pytest.raises(FeederError, match="positive"):
        sim.get_preset({"x": dict(FAST, substeps=0)}, "x")


def test_merge_pieces_hand_cases():
    from shapely.geometry import Polygon
    from shapely.ops import unary_union

    halves = [
        np.array([(0, 0), (0.02, 0), (0.02, 0.02), (0, 0.02)]),
        np.array([(0.02, 0), (0.04, 0), (0.04, 0.02), (0.02, 0.02)]),
    ]
    merged = simbody.merge_pieces(halves, 0.0)  # the union is exactly convex: one piece
    assert len(merged) == 1 and Polygon(merged[0]).area == pytest.approx(8e-4)
    ell = [
        np.array([(0, 0), (0.04, 0), (0.04, 0.01), (0, 0.01)]),
        np.array([(0, 0.01), (0.01, 0.01), (0.01, 0.03), (0, 0.03)]),
    ]
    assert len(simbody.merge_pieces(ell, 2e-4)) == 2  # an L's corner is far deeper than 0.2 mm
    # a shallow notch (0.1 mm deep) is filled at 0.2 mm, kept at 0
    notch = [
        np.array([(0, 0), (0.02, 0), (0.02, 0.0099), (0, 0.01)]),
        np.array([(0.02, 0), (0.04, 0), (0.04, 0.01), (0.02, 0.0099)]),
    ]
    assert len(simbody.merge_pieces(notch, 2e-4)) == 1 and len(simbody.merge_pieces(notch, 0.0)) == 2
    # the merged shape never leaves the true outline by more than the tolerance
    from feeder.parts.geometry import load_part

    g = load_part(ROOT / "parts" / "crescent-a.stl")
    pieces = simbody.merge_pieces(g.convex_pieces, 2e-4)
    assert len(pieces) < len(g.convex_pieces)
    true = Polygon(g.outline)
    approx = unary_union([Polygon(p) for p in pieces])
    assert approx.difference(true.buffer(2e-4 + 1e-9, join_style=2)).area < 1e-12
    assert true.difference(approx).area < 1e-12


# ------------------------------------------------------------------------------------------
# compliant belt contact (scene.belt.contact_stiffness / contact_damping)
# ------------------------------------------------------------------------------------------
def _compliant(k=1000.0, d=1.0):
    scene = copy.deepcopy(SCENE)
    scene["belt"].update(contact_stiffness=k, contact_damping=d)
    return scene


def test_belt_contact_settings_go_together():
    assert sc.belt_contact({"contact_stiffness": None, "contact_damping": None}) is None
    assert sc.belt_contact({}) is None
    assert sc.belt_contact({"contact_stiffness": 1000, "contact_damping": 1}) == (1000.0, 1.0)
    for k, d in [(1000, None), (None, 1.0), (0, 1.0), (1000, -1.0)]:
        with pytest.raises(FeederError, match="contact_stiffness"):
            sc.belt_contact({"contact_stiffness": k, "contact_damping": d})
    assert sc.belt_contact_row(_compliant()["belt"])[1] == "1000 / 1"


def test_compliant_belt_holds_the_part_at_its_half_thickness():
    scene = _compliant()
    model = simbody.part_model(RECT, scene)
    plan = sim.make_plan(scene, parse_location("straight:45"), parse_location("none"), model, False)
    w = simbody.World(scene, FAST, plan, 1, model)
    try:
        info = w.pb.getDynamicsInfo(w.belts[0], -1)
        assert info[9] == pytest.approx(1000.0) and info[8] == pytest.approx(1.0)  # stiffness, damping
        w.reset_belt(0)
        body = w.add_part(0, 0.0, plan.start_y - 0.3, 0.0)
        for _ in range(400):
            w.step()
        pos, _ = w.pb.getBasePositionAndOrientation(body)
        vel, _ = w.pb.getBaseVelocity(body)
        assert abs(pos[2] - 0.0025) < 1e-4 and abs(vel[1] - SCENE["belt"]["speed"]) < 1e-3
    finally:
        w.close()


def test_compliant_belt_makes_the_outcome_independent_of_the_ride_before_the_fences():
    """With rigid contact the weight split over a flat part's contact points depends on how long
    it rode (docs/simulation.md: the C below turns 2.3 deg differently, drop by drop, when placed
    just before the fences instead of at the belt start). A compliant belt fixes the split."""
    scene, part = _compliant(), shape_part("c-40x30x8", 0.005)
    l1, l2 = parse_location("straight:45"), parse_location("straight:30")
    short = simulate(part, l1, l2, 12, 1, scene, FAST)
    full = simulate(part, l1, l2, 12, 1, scene, dict(FAST, full_path=True, skip_slides=False))
    d = (short["final_yaw_deg"] - full["final_yaw_deg"] + 180.0) % 360.0 - 180.0
    assert np.isfinite(d).all() and np.median(np.abs(d)) < 0.5


def test_a_part_left_with_a_residual_velocity_by_the_compliant_belt_still_comes_to_rest():
    """After a slide along a 20 deg fence (skipped ahead, velocity kept), Bullet reported a lateral
    velocity of ~1.4 mm/s for this part forever while it did not move at all; judged by that
    velocity it never came to rest and timed out after ~57 s of simulated time. Rest is judged
    from the displacement between checks."""
    scene, part = _compliant(), shape_part("rect-60x20", 0.005)
    out = sim.run_drops(
        part,
        parse_location("straight:20"),
        parse_location("none"),
        np.array([107.75289855403528, 285.3328072351865]),
        scene,
        FAST,
    )
    assert list(out["status"]) == ["ok", "ok"]
    assert (out["diag"]["sim_time"] < 10.0).all() and out["diag"]["skips"].min() >= 1


@pytest.mark.parametrize("name", ["sim.csv", "sim", "sim.npz.tmp"])
def test_simulate_refuses_an_output_name_that_is_not_npz_before_any_work(tmp_path, capsys, name):
    from feeder.cli import main

    out = tmp_path / name
    argv = ["simulate", "--part", str(ROOT / "parts" / "rect-a2.stl"), "--loc1", "straight:30", "--loc2", "none"]
    assert main([*argv, "--drops", "2", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "name it .npz" in err and "\n" not in err and not out.exists()


def test_a_part_in_millimetres_with_its_origin_moved_drops_like_the_metre_part(tmp_path, capsys):
    """CAD tools export millimetres: --units auto (and mm) reads them; neither the units nor
    the file's origin changes a drop (same initial yaws: same basin, within 0.5 deg)."""
    from feeder.cli import main
    from feeder.parts.geometry import load_part

    outline = np.array([[0.0, 0.0], [0.04, 0.0], [0.04, 0.02], [0.0, 0.02]])
    (tmp_path / "m").mkdir(), (tmp_path / "mm").mkdir()
    metres, mm = tmp_path / "m" / "r.stl", tmp_path / "mm" / "r.stl"  # one part id: one seed
    metres.write_bytes(stl_bytes(outline, 0.005))
    mm.write_bytes(stl_bytes((outline + [0.3, -0.7]) * 1000.0, 5.0))
    with pytest.raises(FeederError, match="millimetres"):
        load_part(mm)  # metres by default in the library: refused, with the hint
    assert load_part(mm, "auto").area == pytest.approx(load_part(metres).area)
    outs = {}
    for name, path, units in (("m", metres, "m"), ("mm", mm, "auto"), ("mm-explicit", mm, "mm")):
        out = tmp_path / f"{name}.npz"
        argv = ["simulate", "--part", str(path), "--loc1", "straight:30", "--loc2", "none", "--drops", "3"]
        assert main([*argv, "--yaw-sampling", "grid", "--preset", "coarse", "--units", units, "--out", str(out)]) == 0
        with np.load(out) as z:
            outs[name] = (z["final_yaw_deg"], z["status"], z["initial_yaw_deg"])
    assert "read in mm (--units auto)" in capsys.readouterr().err
    for name in ("mm", "mm-explicit"):
        np.testing.assert_array_equal(outs[name][2], outs["m"][2])  # the same initial yaws
        np.testing.assert_array_equal(outs[name][1], outs["m"][1])
        d = np.abs((outs[name][0] - outs["m"][0] + 180.0) % 360.0 - 180.0)
        assert np.nanmax(d) < 0.5


@pytest.mark.parametrize("wall_mm, refused", [(0.1, True), (0.19, True), (0.25, False)])
def test_a_wall_around_a_hole_thinner_than_two_margins_is_refused(wall_mm, refused):
    """Each convex piece is inset by the collision margin (0.1 mm): a wall of 0.2 mm or less
    between a hole and the outline would vanish from the collision shape (measured: 3 of 4
    pieces kept at exactly 0.2 mm), leaving a notch a fence could push into."""
    margin = float(SCENE["part"]["collision_margin"])
    assert margin == pytest.approx(1e-4)  # the wall widths above are about this margin
    w = 1e-3 * wall_mm
    outline = np.array([(0, 0), (0.04, 0), (0.04, 0.02), (0, 0.02)], float)
    hole = np.array([(w, 0.003), (0.015, 0.003), (0.015, 0.017), (w, 0.017)])
    geom = PartGeometry.from_polygon("thin-wall", outline, 0.003, [hole])
    if refused:
        with pytest.raises(FeederError, match=r"part thin-wall: .* mm of material between a hole and the outline"):
            simbody.part_model(geom, SCENE)
    else:
        model = simbody.part_model(geom, SCENE)
        assert len(model.pieces) == len(geom.convex_pieces)  # every piece kept, the wall included


def test_drops_in_one_reused_client_equal_drops_in_new_clients_bit_for_bit():
    """run_each builds each drop's world in one pybullet client, reset before each drop, instead of
    a new client per drop (~12 ms each). resetSimulation must leave nothing behind: each drop equals,
    to the bit, the same drop run alone in a client of its own (default contact model and preset;
    an L-shape on two fences, with a jammed drop among them)."""
    scene, presets = load_settings()
    preset = sim.get_preset(presets, CFG["sim"]["preset"])
    geom = load_part(ROOT / "parts" / "lshape-a.stl")
    loc1, loc2 = parse_location("straight:45"), parse_location("curved:30")
    yaws = np.array([3.0, 100.0, 181.5, 290.0])
    shared = sim.run_each(geom, loc1, loc2, yaws, scene, preset)
    alone = [sim.run_drops(geom, loc1, loc2, yaws[i : i + 1], scene, preset) for i in range(len(yaws))]
    assert set(shared["status"]) >= {"ok", "jammed"}
    np.testing.assert_array_equal(shared["final_yaw_deg"], np.concatenate([a["final_yaw_deg"] for a in alone]))
    np.testing.assert_array_equal(shared["status"], np.concatenate([a["status"] for a in alone]))
    for key in ("sim_time", "max_speed", "max_omega", "final_x", "final_y"):
        np.testing.assert_array_equal(shared["diag"][key], np.concatenate([a["diag"][key] for a in alone]))


def test_fence_samples_lie_on_the_footprint_outline_at_the_reach_spacing():
    """The reach samples are points of the fences' outlines, ceil(length / spacing) (at least 4) per
    ring, the first at the ring's start."""
    import shapely

    scene, _ = load_settings()
    fences = lane_geometry.scene_fences(scene, parse_location("curved:40"), parse_location("straight:30"))
    rings = []
    for f in fences:
        fp = f.footprint()
        rings += [fp.exterior] if fp.geom_type == "Polygon" else [g.exterior for g in fp.geoms]
    pts = sim.fence_samples(fences)
    counts = [max(4, math.ceil(r.length / sim._REACH_SAMPLE)) for r in rings]
    assert len(pts) == sum(counts)
    start = 0
    for ring, n in zip(rings, counts):
        own = pts[start : start + n]
        assert np.max(shapely.distance(shapely.points(own), ring)) < 1e-12
        np.testing.assert_allclose(own[0], ring.coords[0], atol=1e-15)
        start += n
