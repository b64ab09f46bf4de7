"""The design bench: configurations, the reference grid, the paired check and the table, on
hand-made files (the smoke workflow runs it end to end on real simulations)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from workflow_helpers import ROOT

from feeder.bench import designs as B
from feeder.bench import reference as R
from feeder.config import load_study_config
from feeder.errors import FeederError


def settings():
    return load_study_config("config/smoke.yaml", root=ROOT)


def test_entries_cover_the_panel_and_the_library_with_file_safe_keys():
    cfg = settings()
    keys = [e["key"] for e in R.entries(cfg)]
    assert keys == ["rect-40x20__straight45_none", "tri-40x25__curved45_straight30", "rect-a2__straight45_none"]
    cfg["sim"]["design_bench"]["library"].append(["rect-a2", "straight:45", "none"])
    with pytest.raises(FeederError, match="listed twice"):
        R.entries(cfg)


def test_reference_grid_covers_one_symmetry_period_evenly():
    yaws, period, offset = R.reference_grid(4, 2880, seed=7)
    assert period == 90.0 and yaws.size == 720 and 0 <= offset < 0.125
    np.testing.assert_allclose(np.diff(yaws), 0.125)
    assert yaws[-1] < offset + 90.0


def _files(tmp_path, step_at=120.0):
    """A reference of a step map (β < step → 30°, else 200°) whose paired real drops disagree
    with the map at one of four yaws, and an adaptive run of four samples."""
    ref = np.arange(0, 360, 0.5) + 0.1
    final = np.where(ref < step_at, 30.0, 200.0)
    entry = {"key": "x__straight30_none"}
    meta = {"entry": entry, "symmetry_order": 1, "period_deg": 360.0, "offset_deg": 0.1, "preset": "fast"}
    reference, adaptive = tmp_path / "ref.npz", tmp_path / "ada.npz"
    np.savez(
        reference,
        ref_initial=ref,
        ref_final=final,
        ref_status=np.full(ref.size, "ok"),
        ref_cpu_s=np.float64(7.2),
        paired_initial=np.array([10.0, 100.0, 200.0, 300.0]),
        paired_final=np.array([30.2, 30.0, 200.0, 20.0]),  # the last drop flipped basin
        paired_status=np.array(["ok", "ok", "ok", "ok"]),
        meta=np.array(json.dumps(meta)),
    )
    design = {
        "period_deg": 360.0,
        "offset_deg": 0.1,
        "tolerance_deg": 2.0,
        "min_width_deg": 0.5,
        "max_width_deg": 90.0,
        "band_gap_deg": 2.0,
        "edge_check_deg": 1.0,
        "calls": 1,
    }
    ada = np.array([0.1, 90.1, 180.1, 270.1])
    np.savez(
        adaptive,
        adaptive4_initial=ada,
        adaptive4_final=np.where(ada < step_at, 30.0, 200.0),
        adaptive4_status=np.full(4, "ok"),
        adaptive4_cpu_s=np.float64(0.04),
        meta=np.array(
            json.dumps(
                {
                    "entry": entry,
                    "adaptive": {"n0": 4, "tolerance_deg": 2.0, "min_width_deg": 0.5, "symmetry": "auto"},
                    "budgets": [{"budget": 4, "design": design}],
                }
            )
        ),
    )
    return reference, adaptive


def test_paired_check_counts_basin_flips_drop_by_drop(tmp_path):
    reference, _ = _files(tmp_path)
    with np.load(reference) as z:
        check = B.paired_check(z, B.reference_design(z, 2.0))
    assert check["paired_same_status"] == 1.0 and check["paired_same_basin"] == 0.75
    assert check["paired_median_dyaw_deg"] == pytest.approx(0.0)  # median of 0.2, 0, 0 among same-basin drops


def test_paired_basins_compares_drop_by_drop_across_the_wrap_and_the_statuses():
    nan = np.nan
    fa = [359.0, 10.0, 100.0, nan, nan, 50.0, 200.0, nan]
    sa = ["ok", "ok", "ok", "jammed", "fell_off", "ok", "ok", "jammed"]
    fb = [1.0, 370.5, 110.0, nan, nan, nan, 195.1, nan]
    sb = ["ok", "ok", "ok", "jammed", "jammed", "jammed", "ok", "jammed"]
    # pairs: 2° across 0/360 (same), 0.5° across a full turn (same), 10° (flip), jammed/jammed
    # (same), fell_off/jammed (flip), ok/jammed (flip), 4.9° (same), jammed/jammed (same)
    c = B.paired_basins(fa, sa, fb, sb)
    assert c["n"] == 8 and c["same_status"] == 6 / 8 and c["same_basin"] == 5 / 8
    assert c["median_dyaw_deg"] == pytest.approx(2.0) and c["max_dyaw_deg"] == pytest.approx(4.9)
    # signed a - b of the same-basin ok pairs: 359 - 1 -> -2, 10 - 370.5 -> -0.5, 200 - 195.1 = 4.9
    assert c["median_signed_dyaw_deg"] == pytest.approx(-0.5)
    # a tighter basin keeps only the 0.5° pair among the ok ones (plus the two jammed pairs)
    tight = B.paired_basins(fa, sa, fb, sb, tolerance_deg=1.0)
    assert tight["same_basin"] == 3 / 8 and tight["median_dyaw_deg"] == pytest.approx(0.5)
    assert tight["max_dyaw_deg"] == pytest.approx(0.5) and tight["median_signed_dyaw_deg"] == pytest.approx(-0.5)
    # symmetric in its two runs, except the sign of the signed difference
    swapped = B.paired_basins(fb, sb, fa, sa)
    assert swapped.pop("median_signed_dyaw_deg") == pytest.approx(0.5)
    assert swapped == {k: v for k, v in c.items() if k != "median_signed_dyaw_deg"}


def test_paired_basins_signed_median_sees_a_shift_the_absolute_median_hides():
    # every drop turned +0.2 deg (across the wrap too) against +-0.2 deg in balance: the same |d|
    # median, but only the shift has a signed median
    base = np.array([359.9, 0.05, 90.0, 180.0, 270.0])
    shifted = B.paired_basins(base + 0.2, ["ok"] * 5, base, ["ok"] * 5)
    assert shifted["median_dyaw_deg"] == pytest.approx(0.2) and shifted["median_signed_dyaw_deg"] == pytest.approx(0.2)
    balanced = B.paired_basins(base[:4] + np.array([0.2, -0.2, 0.2, -0.2]), ["ok"] * 4, base[:4], ["ok"] * 4)
    assert balanced["median_signed_dyaw_deg"] == pytest.approx(0.0) and balanced["median_dyaw_deg"] == pytest.approx(
        0.2
    )


def test_paired_basins_tolerance_is_strict_and_negative_yaws_wrap():
    c = B.paired_basins([0.0, -1.0, 180.0], ["ok"] * 3, [355.0, 359.0, 0.0], ["ok"] * 3)
    # 5° exactly is not below the 5° tolerance; -1° is 359°; half a turn apart is a flip
    assert c["same_basin"] == 1 / 3 and c["median_dyaw_deg"] == 0.0 and c["max_dyaw_deg"] == 0.0
    assert c["median_signed_dyaw_deg"] == 0.0


def test_paired_basins_without_ok_pairs_or_without_pairs():
    jam = B.paired_basins([np.nan, 5.0], ["jammed", "ok"], [np.nan, np.nan], ["jammed", "timed_out"])
    assert jam["same_basin"] == 0.5 and np.isnan(jam["median_dyaw_deg"]) and np.isnan(jam["max_dyaw_deg"])
    assert np.isnan(jam["median_signed_dyaw_deg"])
    empty = B.paired_basins([], [], [], [])
    assert empty["n"] == 0 and np.isnan(empty["same_basin"]) and np.isnan(empty["median_dyaw_deg"])
    with pytest.raises(FeederError, match="differ in shape"):
        B.paired_basins([1.0, 2.0], ["ok", "ok"], [1.0], ["ok"])


def test_table_rows_measure_each_design_against_the_reference(tmp_path):
    cfg = settings()
    cfg["sim"]["design_bench"] |= {"drop_levels": [20, 400], "repeats": 4}
    frame = pd.DataFrame(B.entry_rows(*_files(tmp_path), cfg))
    ref = frame[frame.design == "reference"].iloc[0]
    assert ref.sup_cdf == 0.0 and ref.simulations == 720 and ref.cpu_s == 7.2
    ada = frame[frame.design == "adaptive"].iloc[0]
    # four samples; the map jumps at 120 and at 360/0 (200 → 30), so the intervals [90.1, 180.1) and
    # [270.1, 360.1) are split half and half: 30° gets 0.25 + 0.125 + 0.125 = 1/2 against 1/3
    assert ada.sup_cdf == pytest.approx(0.5 - 1.0 / 3.0, abs=0.01) and ada.simulations == 4
    emulated = frame[frame.design.isin(["random", "grid"])]
    assert set(emulated.repeat) == {0, 1, 2, 3} and (emulated.cpu_s == 0.01 * emulated.drops).all()
    big = frame[(frame.design == "grid") & (frame.drops == 400)]
    assert (big.sup_cdf < 0.01).all()  # a 400-yaw grid of a step map is nearly exact
    means = B.summary(frame)
    rnd = means[(means.design == "random") & (means.drops == 20)].iloc[0]
    assert rnd.sup_cdf_lo <= rnd.sup_cdf <= rnd.sup_cdf_hi and rnd.configurations == 1


def test_emulated_adaptive_refines_the_reference_map_and_finds_its_jumps(tmp_path):
    """The adaptive design run on the reference map: a step map is exact up to the bisection width
    (each of its two jumps misplaces at most half of min_width), at any offset, within budget."""
    cfg = settings()
    cfg["sim"]["design_bench"] |= {"drop_levels": [20], "repeats": 3}
    cfg["sim"]["yaw_sampling"] = "random"  # the study's own budget is not emulated then
    frame = pd.DataFrame(B.entry_rows(*_files(tmp_path), cfg))
    emu = frame[frame.design == "adaptive_emulated"]
    assert len(emu) == 3 and (emu.drops == 4).all() and (emu.simulations == 4).all()  # the file's budget 4
    with np.load(_files(tmp_path)[0]) as z:
        ref = B.reference_design(z, 2.0)
    adaptive = {"n0": 8, "tolerance_deg": 2.0, "min_width_deg": 0.5}
    for seed in range(3):
        label = B.emulated_adaptive(ref, 1, 64, seed, adaptive, 360, 0.0)
        assert label.simulations <= 64
        mass_30 = label.pmf[30]  # the basin of β < 120: a third of the turn
        assert mass_30 == pytest.approx(1.0 / 3.0, abs=2 * 0.25 / 360 + 1e-9)


def test_the_studys_own_adaptive_budget_is_emulated_beside_the_real_runs_budgets(tmp_path):
    """An adaptive study at a budget never simulated for real (here 12, the file has 4) still gets
    its rows: the refinement on the reference map, at most that many simulations, more than 4."""
    cfg = settings()
    cfg["sim"] |= {"yaw_sampling": "adaptive", "drops": 12}
    cfg["sim"]["design_bench"] |= {"drop_levels": [20], "repeats": 2}
    frame = pd.DataFrame(B.entry_rows(*_files(tmp_path), cfg))
    emu = frame[frame.design == "adaptive_emulated"]
    assert sorted(set(emu.drops)) == [4, 12] and len(emu) == 4
    own = emu[emu.drops == 12]
    assert (own.simulations <= 12).all() and (own.simulations > 4).all()
    assert (frame[frame.design == "adaptive"].drops == 4).all()  # the real rows stay the file's own
    assert B.emulated_budgets(
        {"budgets": [{"budget": 64}, {"budget": 32}]}, {"yaw_sampling": "adaptive", "drops": 40}
    ) == [
        32,
        40,
        64,
    ]
    assert B.emulated_budgets({"budgets": [{"budget": 64}]}, {"yaw_sampling": "adaptive", "drops": 64}) == [64]
    assert B.emulated_budgets({"budgets": [{"budget": 64}]}, {"yaw_sampling": "golden", "drops": 40}) == [64]


def test_unknown_configuration_is_a_one_line_error(capsys):
    from feeder.cli import main

    assert (
        main(["bench-designs", "run", "--configfile", "config/smoke.yaml", "--key", "nope", "--out", "/tmp/x.npz"]) == 2
    )
    assert "no configuration 'nope'" in capsys.readouterr().err


def test_summary_leaves_out_configurations_without_a_reference_label_and_scores_missing_labels():
    def rows(config, values, no_label=()):
        return [
            {
                "config": config,
                "design": "random",
                "drops": 50,
                "repeat": r,
                "simulations": 50,
                "cpu_s": 1.0,
                "no_label": r in no_label,
                "sup_cdf": v,
                "w1_deg": v,
                "circular_w1_deg": v,
                "js": v,
            }
            for r, v in enumerate(values)
        ]

    frame = pd.DataFrame(
        rows("easy", [0.01, 0.03])
        + rows("hard", [0.5, B.NO_LABEL["sup_cdf"]], no_label=(1,))
        + rows("noref", [np.nan] * 2)
    )
    out = B.summary(frame).iloc[0]
    assert out.configurations == 2 and out.excluded_configurations == 1 and out.no_label == 1
    assert out.sup_cdf == pytest.approx(np.mean([(0.01 + 0.5) / 2, (0.03 + 1.0) / 2]))
    assert out.sup_cdf_lo < out.sup_cdf < out.sup_cdf_hi


def test_summary_leaves_out_configurations_the_study_drops_as_bad_data():
    """A reference with less ok mass than sim.min_ok_mass (nearly every drop jams) is not scored."""

    def rows(config, ok_mass, value):
        common = {"config": config, "simulations": 50, "cpu_s": 1.0, "no_label": False}
        scores = dict.fromkeys(B.METRICS, value)
        ref = {
            **common,
            "design": "reference",
            "drops": 2880,
            "repeat": 0,
            "ok_mass": ok_mass,
            **dict.fromkeys(B.METRICS, 0.0),
        }
        return [ref] + [
            {**common, "design": "random", "drops": 50, "repeat": r, "ok_mass": ok_mass, **scores} for r in range(2)
        ]

    frame = pd.DataFrame(rows("ok", 0.9, 0.01) + rows("jams", 0.002, 0.9))
    kept = B.summary(frame, min_ok_mass=0.5).set_index("design").loc["random"]
    assert kept.configurations == 1 and kept.excluded_configurations == 1
    assert kept.sup_cdf == pytest.approx(0.01)
    both = B.summary(frame).set_index("design").loc["random"]  # no threshold: both are scored
    assert both.configurations == 2 and both.sup_cdf == pytest.approx((0.01 + 0.9) / 2)


def test_a_killed_reference_run_goes_on_from_its_checkpoint(tmp_path):
    """Chunks are saved as they finish; a rerun simulates only what is left and returns what an
    uninterrupted run returns; a checkpoint of another run (fingerprint) is not used."""
    yaws = np.arange(10, dtype=np.float64)
    calls = []

    def run_chunk(chunk, fail_after=None):
        calls.append(chunk.tolist())
        if fail_after is not None and len(calls) > fail_after:
            raise KeyboardInterrupt  # the session's hard stop
        return 2.0 * chunk, np.full(chunk.size, "ok")

    whole = R.run_resumable(run_chunk, yaws, None, "a", every=3)
    ckpt = tmp_path / "ref.npz.partial.npz"
    calls.clear()
    with pytest.raises(KeyboardInterrupt):
        R.run_resumable(lambda c: run_chunk(c, fail_after=2), yaws, ckpt, "a", every=3)
    assert ckpt.is_file()
    calls.clear()
    final, status, cpu = R.run_resumable(run_chunk, yaws, ckpt, "a", every=3)
    assert calls == [[6.0, 7.0, 8.0], [9.0]]  # two chunks were saved; only the rest is simulated
    np.testing.assert_array_equal(final, whole[0])
    assert (status == "ok").all() and cpu >= 0
    calls.clear()
    R.run_resumable(run_chunk, yaws, ckpt, "other settings", every=3)
    assert calls[0] == [0.0, 1.0, 2.0]  # another run's checkpoint: start over
    ckpt.write_bytes(b"not an npz")
    calls.clear()
    R.run_resumable(run_chunk, yaws, ckpt, "a", every=3)
    assert calls[0] == [0.0, 1.0, 2.0]  # an unreadable checkpoint: start over
