"""The analytic model calibrated on a known part's own labels (feeder.learn.structured_calibration)
and the turn settings of the analytic model's variants (feeder.mechanics.candidates.Variant),
against hand-computed values."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from omegaconf import OmegaConf
from test_structured import TOY_PROTOCOL, _toy_library

from feeder.errors import FeederError
from feeder.learn.structured_calibration import (
    base_and_mode_w1,
    cached_mode_pmfs,
    calibrated_modes,
    calibrated_pmfs,
    calibration_settings,
    compute_mode_pmfs,
    mode_w1,
    with_calibration,
)
from feeder.mechanics.candidates import Variant, variant_pmf, variants_from_config
from feeder.mechanics.distribution import analytic_distribution
from feeder.mechanics.fence import default_scene, fence_models


# ----------------------------------------------------------------------------------------------
# The choice of mode, by hand
# ----------------------------------------------------------------------------------------------
def test_each_row_is_answered_by_the_mode_its_parts_other_training_rows_choose():
    # part a: rows 0-2 train, row 3 scored; part b: row 4 trains alone, row 5 scored; row 6 has no label
    w1 = np.array(
        [
            [10.0, 2.0, 9.0],
            [10.0, 4.0, 9.0],
            [10.0, 12.0, 9.0],
            [7.0, 7.0, 7.0],
            [5.0, 4.8, 1.0],
            [3.0, 3.0, 3.0],
            [np.nan, np.nan, np.nan],
        ]
    )
    parts = np.array(["a", "a", "a", "a", "b", "b", "b"])
    pool = np.array([True, True, True, False, True, False, True])
    got = calibrated_modes(w1, parts, pool, margin_deg=0.5)
    # row 0 sees rows 1, 2: means (10, 8, 9) -> mode 1 beats base by 2; row 1 sees 0, 2: (10, 7, 9) -> 1;
    # row 2 sees 0, 1: (10, 3, 9) -> 1; row 3 (scored) sees all three: (10, 6, 9) -> 1
    assert got[:4].tolist() == [1, 1, 1, 1]
    # row 4 trains alone: no other row, the base; row 5 sees row 4 (row 6 has no label): mode 2
    assert got[4] == 0 and got[5] == 2 and got[6] == 2
    # a margin above every gain keeps the base everywhere
    assert calibrated_modes(w1, parts, pool, margin_deg=7.1).tolist() == [0, 0, 0, 0, 0, 0, 0]
    # the margin is inclusive: row 3's mode 1 gains exactly 4
    assert calibrated_modes(w1, parts, pool, margin_deg=4.0)[3] == 1
    # ties go to the first column: two modes equally good
    tie = np.array([[5.0, 1.0, 1.0], [5.0, 1.0, 1.0]])
    assert calibrated_modes(tie, np.array(["p", "p"]), np.array([True, False]), 0.0).tolist() == [0, 1]
    with pytest.raises(FeederError, match="margin_deg"):
        calibrated_modes(w1, parts, pool, margin_deg=-1.0)


def test_the_chosen_pmfs_and_their_w1():
    base = np.tile(np.eye(4)[0], (3, 1))  # all mass in bin 0
    modes = np.stack([np.tile(np.eye(4)[1], (3, 1)), np.tile(np.eye(4)[3], (3, 1))], axis=1)  # bins 1 and 3
    got = calibrated_pmfs(base, modes, np.array([0, 1, 2]))
    assert got.tolist() == [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 1]]
    # the label in bin 3: W1 (in bins of 90 deg) 1 bin from bin 0 round the circle, 2 from bin 1, 0 from bin 3
    cdf = np.cumsum(np.tile(np.eye(4)[3], (3, 1)), axis=1)
    w1 = mode_w1(cdf, np.concatenate([base[:, None], modes], axis=1), np.array([True, True, False]))
    assert w1[:2] == pytest.approx(np.array([[90.0, 180.0, 0.0]] * 2))
    assert np.isnan(w1[2]).all()


def test_calibration_settings_are_checked():
    cfg = OmegaConf.create({"calibration": {"margin_deg": 0.5, "modes": [{"name": "swing", "graze": "swing"}]}})
    modes, margin = calibration_settings(cfg)
    assert margin == 0.5 and modes == (Variant("swing", graze="swing"),)
    assert calibration_settings(OmegaConf.create({}))[0] == ()
    assert calibration_settings(OmegaConf.create({"calibration": {"margin_deg": 0.0, "modes": []}}))[0] == ()
    for bad, match in (
        ({"margin_deg": -1, "modes": []}, "margin_deg"),
        ({"margin_deg": True, "modes": []}, "margin_deg"),
        ({"margin_deg": 0.5, "modes": [{"name": "same"}]}, "change nothing"),
        ({"margin_deg": 0.5, "modes": [{"name": "x", "grazing": "swing"}]}, "unknown settings"),
        ({"margin_deg": 0.5, "modes": [{"name": "x", "graze": "glide"}]}, "graze must be one of"),
        ({"margin_deg": 0.5, "modes": [{"name": "x", "turn_budget_scale": 0}]}, "turn_budget_scale"),
        ({"margin_deg": 0.5, "modes": [{"name": "x", "turn_rate": "fast"}]}, "turn_rate must be one of"),
    ):
        with pytest.raises(FeederError, match=match):
            calibration_settings(OmegaConf.create({"calibration": bad}))


def test_the_study_config_holds_the_ten_modes_and_the_margin_chosen_on_training_rows():
    from feeder.config import compose_config
    from feeder.learn.structured_calibration import calibration_network

    cfg = compose_config("structured")
    modes, margin = calibration_settings(cfg)
    assert margin == 0.5 and len(modes) == 10 and len({m.name for m in modes}) == 10
    assert calibration_network(cfg)  # won on validation at stop 73


# ----------------------------------------------------------------------------------------------
# Variants with the model's turn settings
# ----------------------------------------------------------------------------------------------
def test_a_variant_spec_names_only_the_turn_settings_it_changes():
    # the five settings the candidate variants had before: their cache key stays the same
    assert Variant("base").spec() == {"name": "base", "mu": None, "exit_turns": True, "jams": True, "fences": "both"}
    got = Variant("m", turn_rate="moment", turn_budget_scale=3.0, arc_ride=None).spec()
    assert got["turn_rate"] == "moment" and got["turn_budget_scale"] == 3.0 and got["arc_ride"] is None
    assert "graze" not in got
    vs = variants_from_config([{"name": "n", "arc_ride": None}, {"name": "d"}])
    assert vs[0].arc_ride is None and vs[1] == Variant("d")


@pytest.mark.parametrize(
    "settings, loc1, loc2",
    [
        ({"graze": "swing"}, "curved:80", "none"),
        ({"turn_rate": "moment", "turn_budget_scale": 1.0}, "curved:30", "straight:20"),
        ({"arc_ride": "basin"}, "curved:30", "straight:20"),
        ({"turn_budget_scale": 1.0}, "curved:30", "straight:20"),
    ],
)
def test_a_variant_pmf_is_the_analytic_distribution_with_its_settings(settings, loc1, loc2):
    from feeder.mechanics.hull import push_geometry
    from feeder.mechanics.pmf import bin_masses
    from feeder.parts.geometry import load_profile

    parts_dir, _ = _library_part()
    geom = push_geometry(*load_profile(parts_dir / "crescent-b.stl", "auto")[:2])  # a concave part: every setting shows
    scene = default_scene()
    got, ok = variant_pmf(geom, loc1, loc2, scene, Variant("v", **settings))
    dist = analytic_distribution(geom, None, None, scene, fences=fence_models(loc1, loc2, scene), **settings)
    want = bin_masses(dist.yaws, dist.weights, 360)
    assert got == pytest.approx(want / want.sum(), abs=1e-12) and ok == pytest.approx(dist.ok_mass)
    base, _ = variant_pmf(geom, loc1, loc2, scene, Variant("base"))
    assert np.abs(got - base).sum() > 0.2  # the setting moves mass here: dropped, this test fails


# ----------------------------------------------------------------------------------------------
# The modes' PMFs of a library part, computed and cached
# ----------------------------------------------------------------------------------------------
def _library_part():
    from pathlib import Path

    parts_dir = Path(__file__).resolve().parents[1] / "parts"
    return parts_dir, "rrect-a"


def test_mode_pmfs_match_the_variant_pmfs_and_do_not_depend_on_workers(tmp_path):
    from feeder.lane.fences import parse_config_id
    from feeder.mechanics.hull import push_geometry
    from feeder.parts.geometry import load_profile

    parts_dir, part = _library_part()
    modes = (Variant("swing", graze="swing"), Variant("mu5", mu=0.5))
    cids = ["straight30_none", "curved50_straight40", "curved80_none"]
    parts = [part, "crescent-b", part]  # two parts: two forked workers, each part's rows put back in place
    args = (parts, cids, [10.0, 0.0, 10.0], default_scene(), modes, 1.0, parts_dir, 360, "auto")
    one = compute_mode_pmfs(*args, workers=1)
    said = []
    two = compute_mode_pmfs(*args, workers=2, progress=said.append)
    assert one.shape == (len(cids), 2, 360) and np.array_equal(one, two)
    assert said == ["calibration modes: 2 of 2 parts"]
    alone = compute_mode_pmfs(["crescent-b"], cids[1:2], [0.0], default_scene(), modes, 1.0, parts_dir, 360, "auto")
    assert np.array_equal(alone[0], one[1])
    outline, holes, _ = load_profile(parts_dir / f"{part}.stl", "auto")
    geom = push_geometry(outline, holes)
    loc1, loc2 = parse_config_id(cids[-1])
    want, _ = variant_pmf(geom, loc1, loc2, default_scene(), modes[0], frame_deg=10.0, smooth_deg=1.0)
    assert one[-1, 0] == pytest.approx(want, abs=1e-15)
    # cached: computed once under a key, then read; another key computes again
    calls = []

    def compute():
        calls.append(1)
        return one

    path = tmp_path / "structured_calibration.npz"
    assert np.array_equal(cached_mode_pmfs(path, "k1", len(cids), compute), one) and len(calls) == 1
    assert np.array_equal(cached_mode_pmfs(path, "k1", len(cids), compute), one) and len(calls) == 1
    cached_mode_pmfs(path, "k2", len(cids), compute)
    assert len(calls) == 2
    with pytest.raises(FeederError, match="part file"):
        compute_mode_pmfs(["no-such-part"], cids[:1], [0.0], default_scene(), modes, 1.0, parts_dir, 360, "auto")
    assert not np.array_equal(one[:, 0], one[:, 1])  # the two modes differ somewhere


# ----------------------------------------------------------------------------------------------
# In the protocol
# ----------------------------------------------------------------------------------------------
def _toy_with_modes():
    """:func:`test_structured._toy_library` with two modes: the first gives every row its own label
    (a perfect mode), the second the analytic PMF turned by 90 deg."""
    a = _toy_library()
    a["mode_pmfs"] = np.stack([a["pmf"], np.roll(a["analytic"], 90, axis=1)], axis=1)
    a["mode_pmfs"][~a["kept"], 0] = a["analytic"][~a["kept"]]
    a["mode_w1"] = base_and_mode_w1(a["cdf"], a["analytic"], a["mode_pmfs"], a["kept"])
    return a


def test_with_calibration_keeps_the_models_own_pmf_beside_the_calibrated_one():
    a = _toy_with_modes()
    pool = a["split"] == "train"
    c = with_calibration(a, pool, 0.5)
    assert np.array_equal(c["base_analytic"], a["analytic"])
    # the perfect mode wins on every part with another labelled training row; its rows answer their labels
    chosen = (c["calibration_mode"] == 1) & a["kept"]
    assert chosen.any() and np.array_equal(c["analytic"][chosen], a["pmf"][chosen])
    assert np.array_equal(c["analytic"][c["calibration_mode"] == 0], a["analytic"][c["calibration_mode"] == 0])
    assert with_calibration(_toy_library(), pool, 0.5).keys() == _toy_library().keys()  # no modes: unchanged
    again = with_calibration(c, pool, 0.5)  # from a calibrated copy: the same, from the model's own PMF
    assert np.array_equal(again["analytic"], c["analytic"])


def test_a_scored_rows_mode_is_never_chosen_on_its_own_label():
    """A mode perfect on the Main fits' scored rows (Test, Fences) and wrong on every training row:
    chosen on the training rows, it never answers a scored row (a Fences part, whose rows are all
    scored, has no training row and keeps the base)."""
    from feeder.config import compose_config
    from feeder.learn.structured_protocol import protocol_jobs

    a = _toy_with_modes()
    cfg = compose_config("structured", TOY_PROTOCOL)
    for kind, _key, _i, train, scored in protocol_jobs(a, cfg)[0]:
        if kind != "main":
            continue
        scored_rows = np.logical_or.reduce(list(scored.values()))
        trick = np.where(scored_rows[:, None], a["pmf"], np.roll(a["pmf"], 180, axis=1))
        b = dict(a, mode_pmfs=np.stack([a["mode_pmfs"][:, 1], trick], axis=1))
        b["mode_w1"] = base_and_mode_w1(b["cdf"], b["analytic"], b["mode_pmfs"], b["kept"])
        c = with_calibration(b, train, 0.5)
        assert (c["calibration_mode"][scored_rows] != 2).all()
        # had the scored rows been training rows, the trick would win on them
        leaky = with_calibration(b, train | scored_rows, 0.5)
        assert (leaky["calibration_mode"][scored_rows & a["kept"]] == 2).any()


def test_the_protocol_scores_the_calibrated_model_on_known_parts_only():
    pytest.importorskip("torch")
    from feeder.config import compose_config
    from feeder.learn.prior import grids
    from feeder.learn.structured_protocol import comparison_table, run_protocol

    cfg = compose_config("structured", [*TOY_PROTOCOL, "protocol.bootstrap.resamples=50", "calibration.network=false"])
    prior = grids(compose_config("train")["prior"])
    off_long, off_choices = run_protocol(_toy_library(), cfg, prior)
    on_long, on_choices = run_protocol(_toy_with_modes(), cfg, prior)
    calibrated = on_long[on_long.predictor.isin(["analytic_calibrated", "neighbour_gated_calibrated"])]
    assert set(calibrated.experiment) == {"test", "fences"}
    # unseen parts have no label to calibrate on: their fits are the same bit for bit
    unseen = ~on_long.experiment.isin(["test", "fences"])
    pd.testing.assert_frame_equal(
        on_long[unseen].reset_index(drop=True),
        off_long[~off_long.experiment.isin(["test", "fences"])].reset_index(drop=True),
    )
    # the baselines stay the model's own PMF; the perfect mode answers the label where it was chosen
    for name in ("analytic_pmf", "analytic_prior", "mean_pmf", "neighbour_gated"):
        a = on_long[(on_long.predictor == name)].reset_index(drop=True)
        b = off_long[(off_long.predictor == name)].reset_index(drop=True)
        pd.testing.assert_frame_equal(a, b)
    key = ["experiment", "repeat", "part", "config_id"]
    known = on_long.experiment.isin(["test", "fences"]) & on_long.kept
    cal = on_long[known & (on_long.predictor == "analytic_calibrated")].set_index(key).cw1
    ana = on_long[known & (on_long.predictor == "analytic_pmf")].set_index(key).cw1.reindex(cal.index)
    assert cal.mean() < ana.mean() and (cal <= ana + 1e-9).all()
    main = on_choices[on_choices.fit.str.startswith("main")]
    assert (main.calibrated_rows > 0).all() and on_choices[
        ~on_choices.fit.str.startswith("main")
    ].calibrated_rows.isna().all()
    table = comparison_table(on_long, {"resamples": 50, "level": 0.95, "seed": 0})
    assert set(table[table.baseline == "analytic_calibrated"].experiment) == {"test", "fences"}
    # calibration.network false: the network is the uncalibrated one, bit for bit
    for name in ("structured", "structured_ensemble"):
        pd.testing.assert_frame_equal(
            on_long[on_long.predictor == name].reset_index(drop=True),
            off_long[off_long.predictor == name].reset_index(drop=True),
        )
    assert not main.calibrated_network.any()
    net_cfg = compose_config("structured", [*TOY_PROTOCOL, "calibration.network=true", "protocol.fits=[main]"])
    net_long, net_choices = run_protocol(_toy_with_modes(), net_cfg, prior)
    assert net_choices.calibrated_network.all()
    mine = net_long[(net_long.predictor == "structured") & net_long.kept].cw1.to_numpy()
    theirs = on_long[on_long.experiment.isin(["test", "fences"]) & (on_long.predictor == "structured") & on_long.kept]
    assert mine.shape == theirs.cw1.shape and not np.allclose(mine, theirs.cw1.to_numpy())
    with pytest.raises(FeederError, match="calibration.network"):
        calibration_settings(OmegaConf.create({"calibration": {"network": "yes"}}))
