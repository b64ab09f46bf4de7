"""Every label's audit (feeder.labels.audit, ``feeder audit``): the audit yaws, the estimate from a
simulation file and its audit drops against the estimator fed directly, stale or foreign audit
files refused, the table and its summary, bad input, and a real audit simulating under the
label's own physics."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from feeder.circular import LABEL_BINS, LABEL_SIGMA_BINS
from feeder.cli import main
from feeder.errors import FeederError
from feeder.labels import audit as A
from feeder.lane.fences import parse_config_id
from feeder.sim import errest as E
from feeder.sim.adaptive import design_from_samples
from feeder.sim.drops import drop_seed
from feeder.sim.pushforward import pushforward_pmf
from feeder.sim.record import BadData, load_sim, write_sim
from feeder.sim.simulate import design_record, run_design

ROOT = Path(__file__).resolve().parents[1]
ADAPTIVE = {"n0": 16, "tolerance_deg": 2.0, "min_width_deg": 0.5, "stop_if_none_ok": True}
SETTINGS = {
    "labels": {"bins": LABEL_BINS, "sigma_bins": LABEL_SIGMA_BINS},
    "sim": {"min_ok_mass": 0.5, "adaptive_target": dict(E.DEFAULT_TARGET)},
}


def two_basins(yaws):
    """Two basins (40° and 220°), a jam arc at 300-310° and a 3° island of 130° inside the first."""
    y = np.mod(np.asarray(yaws, float), 360.0)
    final = np.where(y < 200.0, 40.0, 220.0)
    final = np.where((y > 95.0) & (y < 98.0), 130.0, final)
    status = np.where((y > 300.0) & (y < 310.0), "jammed", "ok")
    return final, status


def all_jam(yaws):
    y = np.asarray(yaws, float)
    return np.zeros_like(y), np.full(y.shape, "jammed")


def write_record(path, part, cfg, fmap, budget=24, order=1, seed=0):
    """A simulation file as feeder simulate writes it for the adaptive design, with ``fmap`` as the simulator."""
    design = run_design(fmap, drop_seed(part, cfg, seed), budget, ADAPTIVE, order)
    arrays, summary = design_record(design, order)
    loc1, loc2 = parse_config_id(cfg)
    meta = {
        "part": part,
        "loc1": loc1.spec,
        "loc2": loc2.spec,
        "config_id": cfg,
        "seed": seed,
        "drops": budget,
        "yaw_sampling": "adaptive",
        "simulations": int(design.yaws.size),
        "settings": {"scene": {}, "preset": {}},
        "design": summary | {"n0": 16, "stop": "budget"},
    }
    write_sim(
        path,
        {
            "final_yaw_deg": design.final,
            "initial_yaw_deg": design.yaws,
            "status": design.status,
            "wall_s": np.float64(2.0),
            "cpu_s": np.float64(2.0),
            "meta": json.dumps(meta),
            **arrays,
        },
    )
    return design


def test_audit_yaws_are_stratified_over_the_period_seeded_by_the_configuration(tmp_path):
    write_record(tmp_path / "a.npz", "p", "straight30_none", two_basins, order=2)
    rec = load_sim(tmp_path / "a.npz")
    d = rec.meta["design"]
    beta = A.audit_plan(rec, 8)
    assert d["period_deg"] == 180.0
    np.testing.assert_array_equal(np.floor((beta - d["offset_deg"]) / 22.5), np.arange(8))  # one per stratum
    np.testing.assert_array_equal(beta, A.audit_plan(rec, 8))  # seeded: the same every time
    write_record(tmp_path / "b.npz", "p", "straight35_none", two_basins, order=2)
    assert not np.allclose(A.audit_plan(load_sim(tmp_path / "b.npz"), 8), beta)  # another configuration, other yaws
    expected = E.audit_yaws(np.random.default_rng([drop_seed("p", "straight30_none", 0), 8]), 8, d["offset_deg"], 180.0)
    np.testing.assert_array_equal(beta, expected)


def test_the_audit_is_the_targeted_designs_next_round_and_a_targeted_label_gets_another(tmp_path):
    """Run on from a budget label with the targeted design (min_budget = the budget), its first audit
    round is the study's audit; a targeted label (meta stop: target) is audited elsewhere."""
    design = write_record(tmp_path / "a.npz", "p", "straight30_curved40", two_basins, budget=24)
    rec = load_sim(tmp_path / "a.npz")
    seed = drop_seed("p", "straight30_curved40", 0)
    target = dict(E.DEFAULT_TARGET, min_budget=24, target_w1_deg=1e-6, target_sup_cdf=1e-6, cap=24 + 8)
    seen = []

    def recording(yaws):
        seen.append(np.array(yaws))
        return two_basins(yaws)

    run_on, _, _ = E.targeted(recording, seed, {**ADAPTIVE, "target": target}, 1, LABEL_BINS, LABEL_SIGMA_BINS)
    before = np.sort(np.mod(np.concatenate(seen[:-1]), 360.0))
    np.testing.assert_array_equal(before, np.sort(np.mod(design.yaws, 360.0)))  # the label's own simulations
    assert run_on.evaluations == design.evaluations + 8
    np.testing.assert_allclose(seen[-1], np.mod(A.audit_plan(rec, 8), 360.0))  # the round after the budget
    meta = dict(rec.meta)
    meta["design"] = dict(meta["design"], stop="target")
    rec.meta = meta
    assert not np.allclose(A.audit_plan(rec, 8), seen[-1])


def test_the_estimate_from_a_file_and_its_audit_drops_is_the_estimators_own(tmp_path):
    """The record round trip rebuilds the design that ran, so the audit stage's estimate equals
    feeder.sim.errest's on that design and the same audit drops."""
    design = write_record(tmp_path / "a.npz", "p", "straight30_curved40", two_basins)
    rec = load_sim(tmp_path / "a.npz", min_ok_drops=0)
    drops = pd.DataFrame(A.audit_rows(rec, 8, two_basins))
    assert list(drops.columns) == list(A.DROP_COLUMNS) and len(drops) == 8
    got = A.estimate_from_audit(rec, drops, LABEL_BINS, LABEL_SIGMA_BINS, 0.9)
    beta = A.audit_plan(rec, 8)
    final, status = two_basins(beta)
    want = E.estimate_or_worst(design, beta, final, status, LABEL_BINS, LABEL_SIGMA_BINS, 0.9)
    assert got == want
    # and it bounds the label's true error against the exact map (a dense push-forward)
    dense = np.arange(0.0, 360.0, 0.01)
    exact = design_from_samples(
        dense, *two_basins(dense), period_deg=360.0, offset_deg=0.0, tolerance_deg=2.0, min_width_deg=0.01
    )
    p_exact = pushforward_pmf(exact, LABEL_BINS, LABEL_SIGMA_BINS)[0]
    p_label = pushforward_pmf(design, LABEL_BINS, LABEL_SIGMA_BINS)[0]
    sup = np.max(np.abs(np.cumsum(p_exact) - np.cumsum(p_label)))
    assert got.sup_cdf >= sup
    from feeder.labels import metrics as L

    assert got.circular_w1_deg >= L.circular_w1(L.cdf(p_exact), L.cdf(p_label))


def test_stale_or_foreign_audit_drops_are_refused(tmp_path):
    write_record(tmp_path / "a.npz", "p", "straight30_none", two_basins)
    rec = load_sim(tmp_path / "a.npz")
    drops = pd.DataFrame(A.audit_rows(rec, 8, two_basins))
    moved = drops.copy()
    moved.loc[3, "initial_yaw_deg"] += 0.5
    with pytest.raises(BadData, match="another simulation file"):
        A.estimate_from_audit(rec, moved, LABEL_BINS, LABEL_SIGMA_BINS, 0.9)
    with pytest.raises(BadData, match="7 audit drops against the count"):
        A.estimate_from_audit(rec, drops.iloc[:7], LABEL_BINS, LABEL_SIGMA_BINS, 0.9)
    with pytest.raises(BadData, match="no audit drops"):
        A.estimate_from_audit(rec, drops.iloc[:0], LABEL_BINS, LABEL_SIGMA_BINS, 0.9)


def test_a_configuration_without_a_label_is_not_audited_and_is_listed_as_such(tmp_path):
    sim = tmp_path / "sim"
    write_record(sim / "p" / "straight30_none.npz", "p", "straight30_none", two_basins)
    write_record(sim / "p" / "straight60_none.npz", "p", "straight60_none", all_jam)
    rec = load_sim(sim / "p" / "straight60_none.npz", min_ok_drops=0)
    assert A.audit_rows(rec, 8, all_jam) == []  # nothing simulated
    ok = load_sim(sim / "p" / "straight30_none.npz")
    drops = pd.DataFrame(A.audit_rows(ok, 8, two_basins))
    entries = [("main", sim / "p" / "straight30_none.npz"), ("main", sim / "p" / "straight60_none.npz")]
    rows = pd.DataFrame(A.label_error_rows(entries, drops, SETTINGS))
    assert rows["kept"].tolist() == [True, False]
    assert rows.loc[1, "audits"] == 0 and np.isnan(rows.loc[1, "est_circular_w1_deg"])
    assert rows.loc[0, "loc1"] == "straight" and rows.loc[0, "loc2"] == "none"
    table = A.summary(rows)
    everything = table[table["fences"] == "all"].iloc[0]
    assert everything["configurations"] == 1  # the kept labels only
    assert everything["est_w1_median"] == pytest.approx(rows.loc[0, "est_circular_w1_deg"])
    assert everything["audit_cpu_over_sim"] == pytest.approx(rows["audit_cpu_s"].sum() / 4.0)  # both files' CPU
    assert rows["sim_cpu_s"].tolist() == [2.0, 2.0]
    with pytest.raises(BadData, match="p straight30_none: no audit drops"):
        A.label_error_rows(entries, drops.iloc[:0], SETTINGS)


def table_argv(source: list[str], audit: Path, out: Path, summary: Path) -> list[str]:
    """``feeder audit table`` on ``source`` (the configuration options) with the tests' settings."""
    files = ["--out-csv", str(out), "--out-summary", str(summary)]
    return ["audit", "table", *source, "--audits", str(audit), "--settings", json.dumps(SETTINGS), *files]


def test_the_table_command_takes_the_studys_list_or_files_of_ones_own(tmp_path, capsys):
    sim = tmp_path / "sim"
    write_record(sim / "p" / "straight30_none.npz", "p", "straight30_none", two_basins)
    rec = load_sim(sim / "p" / "straight30_none.npz")
    audit = tmp_path / "mine.csv"  # any name: drops are matched by their part and configuration columns
    pd.DataFrame(A.audit_rows(rec, 8, two_basins)).to_csv(audit, index=False)
    cfgs = tmp_path / "configurations.csv"
    pd.DataFrame({"part": ["p"], "config_id": ["straight30_none"], "dataset": ["main"]}).to_csv(cfgs, index=False)
    out = {}
    for name, source in (
        ("study", ["--configurations", str(cfgs), "--sim-dir", str(sim)]),
        ("own", ["--sims", str(sim / "p" / "straight30_none.npz")]),
    ):
        csv, summ = tmp_path / f"{name}.csv", tmp_path / f"{name}_summary.csv"
        assert main(table_argv(source, audit, csv, summ)) == 0
        out[name] = pd.read_csv(csv)
    assert out["study"].drop(columns="dataset").equals(out["own"].drop(columns="dataset"))
    bad = tmp_path / "bad.csv"
    assert main(table_argv([], audit, bad, bad)) == 2
    assert "either --configurations (with --sim-dir) or --sims" in capsys.readouterr().err and not bad.exists()


def test_rows_are_joined_by_part_and_configuration_together(tmp_path):
    """Two parts with the same configuration id: each label gets its own part's audit."""
    sim = tmp_path / "sim"
    write_record(sim / "p" / "straight30_none.npz", "p", "straight30_none", two_basins)
    write_record(sim / "q" / "straight30_none.npz", "q", "straight30_none", all_jam)
    write_record(
        sim / "q" / "curved40_none.npz",
        "q",
        "curved40_none",
        lambda y: (np.full(np.shape(y), 77.0), np.full(np.shape(y), "ok")),
    )
    recs = {
        k: load_sim(sim / k[0] / f"{k[1]}.npz", min_ok_drops=0)
        for k in (("p", "straight30_none"), ("q", "curved40_none"))
    }
    drops = pd.concat(
        [
            pd.DataFrame(
                A.audit_rows(
                    recs[("q", "curved40_none")], 8, lambda y: (np.full(np.shape(y), 77.0), np.full(np.shape(y), "ok"))
                )
            ),
            pd.DataFrame(A.audit_rows(recs[("p", "straight30_none")], 8, two_basins)),
        ]
    )
    entries = [
        ("", sim / "q" / "straight30_none.npz"),
        ("", sim / "p" / "straight30_none.npz"),
        ("", sim / "q" / "curved40_none.npz"),
    ]
    rows = pd.DataFrame(A.label_error_rows(entries, drops, SETTINGS))
    assert rows["part"].tolist() == ["q", "p", "q"] and rows["audits"].tolist() == [0, 8, 8]
    want = A.estimate_from_audit(
        recs[("p", "straight30_none")], drops[drops.part == "p"], LABEL_BINS, LABEL_SIGMA_BINS, 0.9
    )
    assert rows.loc[1, "est_circular_w1_deg"] == want.circular_w1_deg
    assert rows.loc[2, "misses"] == 0  # the constant map: every audit agrees


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda f: f.assign(final_yaw_deg=np.nan), "an ok drop has no finite final yaw"),
        (lambda f: f.assign(status=""), "unknown status ''"),
        (lambda f: f.assign(status="exploded"), "unknown status 'exploded'"),
        (lambda f: f.assign(audits="eight"), "column 'audits' holds a value that is not a number"),
        (lambda f: f.assign(initial_yaw_deg="x"), "column 'initial_yaw_deg' holds a value that is not a number"),
        (lambda f: f.drop(columns="cpu_s"), "lacks column 'cpu_s'"),
    ],
)
def test_a_broken_audit_file_is_a_one_line_error(tmp_path, edit, message):
    write_record(tmp_path / "a.npz", "p", "straight30_none", two_basins)
    drops = pd.DataFrame(A.audit_rows(load_sim(tmp_path / "a.npz"), 8, two_basins))
    edit(drops).to_csv(tmp_path / "audit.csv", index=False)
    with pytest.raises(BadData, match=message):
        A.read_drops(tmp_path / "audit.csv")


def test_the_table_writes_nothing_when_it_cannot_finish(tmp_path, capsys):
    write_record(tmp_path / "sim" / "p" / "straight30_none.npz", "p", "straight30_none", two_basins)
    rec = load_sim(tmp_path / "sim" / "p" / "straight30_none.npz")
    pd.DataFrame(A.audit_rows(rec, 8, two_basins)).to_csv(tmp_path / "audit.csv", index=False)
    out, summ = tmp_path / "t.csv", tmp_path / "s.csv"
    empty = tmp_path / "empty.csv"
    empty.write_text("part,config_id\n")
    for source, said in (
        (
            ["--configurations", str(tmp_path / "nowhere.csv"), "--sim-dir", str(tmp_path / "sim")],
            "nowhere.csv is missing",
        ),
        (["--configurations", str(empty), "--sim-dir", str(tmp_path / "sim")], "no configuration to tabulate"),
        (["--configurations", str(empty)], "--configurations needs --sim-dir"),
    ):
        assert main(table_argv(source, tmp_path / "audit.csv", out, summ)) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and said in err[0], err
        assert not out.exists() and not summ.exists()


@pytest.mark.parametrize("audits", [1, 0, -3, True, 2.5])
def test_an_audit_count_below_two_or_not_an_integer_is_refused(audits):
    with pytest.raises(FeederError, match="audits must be an integer of at least 2"):
        A.check_audits(audits)


def run_argv(sim: Path, out: Path, audits: int = 8) -> list[str]:
    """``feeder audit run`` of rect-a2 on one simulation file."""
    part = str(ROOT / "parts" / "rect-a2.stl")
    return ["audit", "run", "--part", part, "--sims", str(sim), "--audits", str(audits), "--out", str(out)]


def test_a_drawn_design_is_refused_before_any_simulation(tmp_path, capsys):
    path = tmp_path / "r.npz"
    meta = {
        "part": "rect-a2",
        "config_id": "straight30_none",
        "seed": 0,
        "yaw_sampling": "random",
        "loc1": "straight:30",
        "loc2": "none",
    }
    write_sim(
        path,
        {
            "final_yaw_deg": np.array([1.0, 2.0]),
            "initial_yaw_deg": np.array([0.0, 9.0]),
            "status": np.array(["ok", "ok"]),
            "wall_s": np.float64(0),
            "cpu_s": np.float64(0),
            "meta": json.dumps(meta),
        },
    )
    out = tmp_path / "audit.csv"
    assert main(run_argv(path, out)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "only grid and adaptive labels are audited" in err[0]
    assert not out.exists()
    assert main(run_argv(path, out, audits=1)) == 2
    assert "at least 2" in capsys.readouterr().err and not out.exists()


def test_a_simulation_file_of_another_part_is_refused(tmp_path, capsys):
    write_record(tmp_path / "a.npz", "lshape-a", "straight30_none", two_basins)
    out = tmp_path / "audit.csv"
    assert main(run_argv(tmp_path / "a.npz", out)) == 2
    assert "is of part 'lshape-a', not 'rect-a2'" in capsys.readouterr().err and not out.exists()


def test_a_real_audit_simulates_under_the_labels_own_physics(tmp_path):
    """The audit's simulator, fed the label's own initial yaws, gives the label's own drops: the
    audit runs the scene and preset the file records, one world per drop. (Within 1e-9 degrees, not
    bit for bit: the file keeps the initial yaws as the design sorted them into its period, which
    may differ from the yaw that was simulated in the last bit.)"""
    from feeder.parts.geometry import load_part

    sim = tmp_path / "straight30_none.npz"
    argv = ["simulate", "--part", str(ROOT / "parts" / "rect-a2.stl"), "--loc1", "straight:30", "--loc2", "none"]
    assert (
        main(
            [*argv, "--drops", "8", "--yaw-sampling", "adaptive", "--n0", "8", "--preset", "coarse", "--out", str(sim)]
        )
        == 0
    )
    with np.load(sim) as z:
        initial, final, status = z["initial_yaw_deg"], z["final_yaw_deg"], z["status"]
    rec = load_sim(sim)
    got_final, got_status = A.simulator(load_part(ROOT / "parts" / "rect-a2.stl"), rec)(np.mod(initial[:3], 360.0))
    np.testing.assert_array_equal(got_status, status[:3])
    np.testing.assert_allclose(got_final, final[:3], rtol=0.0, atol=1e-9)
    out = tmp_path / "audit.csv"
    assert (
        main(
            [
                "audit",
                "run",
                "--part",
                str(ROOT / "parts" / "rect-a2.stl"),
                "--sims",
                str(sim),
                "--audits",
                "2",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    drops = A.read_drops(out)
    assert len(drops) == 2 and set(drops["status"]) <= {"ok", "jammed", "fell_off", "flipped", "timed_out"}
    assert A.estimate_from_audit(rec, drops, LABEL_BINS, LABEL_SIGMA_BINS, 0.9).audits == 2
