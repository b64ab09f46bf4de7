"""Labels from every initial-yaw design: one function (feeder.labels.pmf.sim_label), the
`feeder labels pmf` command on real simulation files, the adaptive design's bad input, and the
symmetry the adaptive design folds over checked in the simulator."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from workflow_helpers import ROOT

from feeder.cli import main as feeder
from feeder.labels import metrics as L
from feeder.labels import pmf as P
from feeder.sim import drops as sim
from feeder.sim import simulate as simulate_cli
from feeder.sim.adaptive import refine
from feeder.sim.pushforward import pushforward_pmf
from feeder.sim.record import SimRecord, load_sim, write_sim

PART = str(ROOT / "parts" / "rect-a2.stl")


def simulate_rect(out, *args) -> int:
    """`feeder simulate` of the 2:1 rectangle on one straight fence (coarse preset)."""
    base = ["simulate", "--part", PART, "--loc1", "straight:45", "--loc2", "none", "--preset", "coarse"]
    return feeder([*base, *args, "--out", str(out)])


def step_map(yaws):
    """Two basins and a jam arc: β < 120 → 30°, 120 ≤ β < 300 → 200°, else jammed."""
    yaws = np.asarray(yaws)
    final = np.where(yaws < 120, 30.0, 200.0)
    status = np.where(yaws >= 300, "jammed", "ok")
    return np.where(status == "ok", final, np.nan), status


def adaptive_record(tmp_path, evaluate=step_map):
    design = refine(evaluate, n0=8, budget=48, offset_deg=3.0)
    arrays, summary = simulate_cli.design_record(design, 1)
    meta = {"part": "x", "config_id": "straight30_none", "seed": 0, "yaw_sampling": "adaptive", "design": summary}
    path = tmp_path / "a.npz"
    write_sim(
        path,
        {
            "final_yaw_deg": design.final,
            "initial_yaw_deg": design.yaws,
            "status": design.status,
            "wall_s": np.float64(0),
            "cpu_s": np.float64(0),
            "meta": json.dumps(meta),
            **arrays,
        },
    )
    return path, design


def test_drawn_design_label_is_the_histogram_of_its_ok_drops():
    yaws = np.array([10.2, 10.7, np.nan, 350.0])
    status = np.array(["ok", "ok", "jammed", "ok"])
    rec = SimRecord(yaws=yaws, ok=status == "ok", meta={"yaw_sampling": "golden"}, status=status)
    label = P.sim_label(rec, 360, 1.0)
    np.testing.assert_array_equal(label.pmf, L.pmf_from_yaws(yaws[status == "ok"], 360, 1.0))
    assert label.masses == {"ok": 0.75, "jammed": 0.25} and np.isnan(label.cdf_bound)
    drop_yaws, ok = P.level_drops(rec, 1000)
    assert drop_yaws is rec.yaws and ok is rec.ok  # the drops themselves, in drop order


def test_adaptive_record_label_is_the_push_forward_of_its_design(tmp_path):
    path, design = adaptive_record(tmp_path)
    rec = load_sim(path)
    label = P.sim_label(rec, 360, 1.0)
    pmf, masses = pushforward_pmf(design, 360, 1.0)
    np.testing.assert_allclose(label.pmf, pmf, atol=1e-15)
    # the exact answer: ok mass 300/360, jammed 60/360, basins 120:180 of the ok mass
    assert masses["jammed"] == pytest.approx(60 / 360, abs=design.unresolved_share)
    raw, _ = pushforward_pmf(design, 360, 0.0)
    assert raw[30] == pytest.approx(120 / 300, abs=2 * label.cdf_bound + 1e-12)
    assert raw[200] == pytest.approx(180 / 300, abs=2 * label.cdf_bound + 1e-12)
    assert label.cdf_bound <= 0.02 and label.simulations == design.evaluations <= 48


def test_emulated_level_drops_follow_the_map_and_are_seeded(tmp_path):
    path, _ = adaptive_record(tmp_path)
    rec = load_sim(path)
    yaws, ok = P.level_drops(rec, 3000)
    yaws2, _ = P.level_drops(rec, 3000)
    np.testing.assert_array_equal(yaws, yaws2)
    assert ok.mean() == pytest.approx(300 / 360, abs=0.03)
    assert set(np.round(yaws[ok])) <= {30.0, 200.0}


def test_min_ok_mass_refuses_a_mostly_jammed_configuration(tmp_path):
    path, _ = adaptive_record(tmp_path, lambda y: (np.full(len(y), 5.0), np.where(np.asarray(y) < 40, "ok", "jammed")))
    label = P.sim_label(load_sim(path), 360, 1.0)
    with pytest.raises(P.BadData, match="ok mass 0.11"):
        P.check_ok_mass(label, 0.5, "x.npz")
    P.check_ok_mass(label, 0.1, "x.npz")


@pytest.mark.parametrize("design", ["random", "golden", "grid", "adaptive"])
def test_labels_pmf_cli_reads_every_design(tmp_path, capsys, design):
    sim_file, out = tmp_path / "s.npz", tmp_path / "pmf.csv"
    drops = "16" if design == "adaptive" else "6"
    extra = ["--n0", "4", "--min-width-deg", "5"] if design == "adaptive" else []
    assert simulate_rect(sim_file, "--drops", drops, "--yaw-sampling", design, *extra) == 0
    capsys.readouterr()
    assert feeder(["labels", "pmf", str(sim_file), "--out", str(out)]) == 0
    summary = json.loads(capsys.readouterr().out)
    frame = pd.read_csv(out)
    assert list(frame.columns) == ["angle_deg", "pmf", "cdf"] and len(frame) == 360
    assert frame.angle_deg.iloc[1] == 1.0 and frame.pmf.sum() == pytest.approx(1.0)
    np.testing.assert_allclose(frame.cdf, np.cumsum(frame.pmf))
    assert summary["design"] == design and sum(summary["masses"].values()) == pytest.approx(1.0, abs=1e-5)
    assert summary["simulations"] == len(load_sim(sim_file).yaws)
    assert (summary["cdf_bound"] is None) == (design in ("random", "golden"))
    if design == "adaptive":  # a 2:1 rectangle: one half-turn simulated, the other mapped
        meta = load_sim(sim_file).meta["design"]
        assert meta["symmetry_order"] == 2 and meta["period_deg"] == 180.0 and meta["evaluations"] <= 16


@pytest.mark.parametrize(
    "args, message",
    [
        (["--drops", "8", "--n0", "16"], "budget"),
        (["--drops", "8", "--n0", "1"], "n0"),
        (["--drops", "16", "--tolerance-deg", "0"], "tolerance"),
        (["--drops", "16", "--symmetry", "3"], "no 3-fold symmetry"),
        (["--drops", "16", "--symmetry", "two"], "symmetry must be auto or a positive integer"),
    ],
)
def test_adaptive_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys, args, message):
    out = tmp_path / "s.npz"
    code = simulate_rect(out, "--yaw-sampling", "adaptive", *args)
    err = capsys.readouterr().err.strip()
    assert code == 2 and message in err and "\n" not in err and "Traceback" not in err
    assert not out.exists()


def test_a_half_turn_of_a_two_fold_part_turns_its_outcome_by_a_half_turn():
    """What folding over symmetry assumes, in the simulator: f(β + 180) = f(β) + 180 for a 2:1
    rectangle (same basin; a sub-degree difference from the rotated decomposition is allowed)."""
    from feeder.lane.fences import parse_location
    from feeder.lane.settings import load_settings
    from feeder.parts.geometry import load_part

    scene, presets = load_settings()
    geom = load_part(PART)
    yaws = np.array([12.0, 75.0, 140.0])
    res = sim.run_drops(
        geom,
        parse_location("straight:45"),
        parse_location("none"),
        np.r_[yaws, yaws + 180.0],
        scene,
        sim.get_preset(presets, "fast"),
    )
    a, b = res["final_yaw_deg"][:3], res["final_yaw_deg"][3:]
    assert list(res["status"]) == ["ok"] * 6
    np.testing.assert_array_less(np.abs(((b - a - 180.0) + 180.0) % 360.0 - 180.0), 0.5)


def test_a_drops_outcome_depends_on_its_yaw_alone_in_worlds_of_its_own():
    """The sampled maps simulate batches of yaws: a yaw's outcome must not depend on what else the
    batch holds or where it sits in it. In one shared world it does (measured: 100° after a
    jammed drop ends 0.04° away from 100° alone); run_each gives every drop its own world."""
    from feeder.lane.fences import parse_location
    from feeder.lane.settings import load_settings
    from feeder.parts.geometry import load_part

    scene, presets = load_settings()
    preset = sim.get_preset(presets, "coarse")
    geom = load_part(ROOT / "parts" / "lshape-a.stl")
    loc1, loc2 = parse_location("straight:30"), parse_location("curved:40")

    def run(yaws, runner=sim.run_each):
        res = runner(geom, loc1, loc2, np.asarray(yaws, dtype=float), scene, preset)
        return res["final_yaw_deg"], res["status"]

    (f_a, s_a), (f_b, s_b), (f_c, s_c) = run([100.0, 250.0, 5.0]), run([5.0, 100.0]), run([250.0])
    assert s_b[0] == "jammed"  # the drop before 100° in the second batch jams
    np.testing.assert_array_equal(f_a[[0, 2]], f_b[[1, 0]])
    np.testing.assert_array_equal(s_a[[0, 2]], s_b[[1, 0]])
    np.testing.assert_array_equal(f_a[1:2], f_c)
    assert s_a[1] == s_c[0]
    shared, _ = run([5.0, 100.0], sim.run_drops)
    assert shared[1] != f_b[1]  # the shared world is what this guards against
