"""The structured predictor of issue #39: candidates (feeder.mechanics.candidates), the mixture
model (feeder.learn.structured) and its protocol (feeder.learn.structured_protocol), against
hand-computed values."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from factories import grid_map

from feeder.errors import FeederError
from feeder.labels.metrics import circular_w1
from feeder.mechanics.candidates import (
    Variant,
    basin_masses,
    candidates_from_pmfs,
    configuration_candidates,
    merge_positions,
    pmf_modes,
    variant_pmf,
    variants_from_config,
    window_sums,
)
from feeder.mechanics.fence import default_scene

BINS = 360


def spikes(masses: dict[int, float], bins: int = BINS) -> np.ndarray:
    p = np.zeros(bins)
    for b, m in masses.items():
        p[b] = m
    return p


# ----------------------------------------------------------------------------------------------
# Candidates: pure functions
# ----------------------------------------------------------------------------------------------
def test_window_sums_wrap_around():
    p = spikes({0: 0.5, 359: 0.25, 10: 0.25})
    s = window_sums(p, 2.0)  # +-2 bins
    assert s[0] == pytest.approx(0.75)  # bins 358..2 hold 359 and 0
    assert s[358] == pytest.approx(0.75)  # bins 356..0
    assert s[357] == pytest.approx(0.25)
    assert s[12] == pytest.approx(0.25) and s[13] == 0.0
    assert s.sum() == pytest.approx(5.0)  # every bin counted in 5 windows


def test_modes_of_two_spikes_including_one_at_the_seam():
    p = spikes({359: 0.6, 90: 0.4})
    pos, mass = pmf_modes(p, min_mass=0.1, window_deg=3.0)
    assert pos.tolist() == [359.5, 90.5]  # heaviest first, bin centres
    assert mass.tolist() == pytest.approx([0.6, 0.4])


def test_a_mode_below_min_mass_and_a_flat_pmf_have_no_mode():
    pos, _ = pmf_modes(spikes({0: 0.95, 180: 0.05}), min_mass=0.1, window_deg=3.0)
    assert pos.tolist() == [0.5]
    pos, _ = pmf_modes(np.full(BINS, 1.0 / BINS), min_mass=0.0, window_deg=3.0)
    assert pos.size == 0


def test_merge_keeps_the_heavier_across_the_seam():
    kept = merge_positions([359.5, 0.5, 180.0], [0.2, 0.7, 0.1], merge_deg=2.0)
    assert kept.tolist() == [0.5, 180.0]
    kept = merge_positions([359.5, 0.5], [0.2, 0.7], merge_deg=0.5)  # 1 deg apart: both stay
    assert kept.tolist() == [0.5, 359.5]


def test_basin_masses_split_by_the_nearer_position_and_cut_at_the_window():
    p = spikes({0: 0.3, 358: 0.2, 5: 0.1, 20: 0.4})
    # positions 359.5 and 4.5: bin 0 (0.5) is 1 from the first, 4 from the second; bin 5 (5.5)
    # is 1 from the second; bin 358 (358.5) is 1 from the first; bin 20 is outside both windows
    m = basin_masses(p, [359.5, 4.5], window_deg=3.0)
    assert m.tolist() == pytest.approx([0.5, 0.1])
    assert basin_masses(p, [], 3.0).size == 0


def test_candidates_from_pmfs_merge_variants_and_report_each_variants_masses():
    a = spikes({10: 0.7, 100: 0.3})
    b = spikes({11: 0.5, 200: 0.5})  # its first mode 1 deg from a's: merged into a's heavier one
    pos, masses = candidates_from_pmfs(np.stack([a, b]), min_mass=0.05, window_deg=3.0, merge_deg=2.0, max_candidates=8)
    assert pos.tolist() == [10.5, 200.5, 100.5]  # by summed mass 1.2, 0.5, 0.3
    assert masses == pytest.approx(np.array([[0.7, 0.5], [0.0, 0.5], [0.3, 0.0]]))
    pos, masses = candidates_from_pmfs(np.stack([a, b]), 0.05, 3.0, 2.0, max_candidates=1)
    assert pos.tolist() == [10.5] and masses.shape == (1, 2)


def test_variants_are_checked():
    vs = variants_from_config([{"name": "base"}, {"name": "slip", "mu": 0.2, "exit_turns": False, "fences": "loc1"}])
    assert vs[1] == Variant("slip", 0.2, False, True, "loc1")
    with pytest.raises(FeederError):
        variants_from_config([{"name": "a"}, {"name": "a"}])
    with pytest.raises(FeederError):
        Variant("x", fences="loc3")
    with pytest.raises(FeederError):
        Variant("x", mu=-1.0)


# ----------------------------------------------------------------------------------------------
# Candidates of a real configuration
# ----------------------------------------------------------------------------------------------
RECT = np.array([(0.0, 0.0), (0.04, 0.0), (0.04, 0.02), (0.0, 0.02)])


def test_rectangle_on_one_fence_candidates_are_its_analytic_modes():
    scene = default_scene()
    variants = (Variant("base"), Variant("loc2_alone", fences="loc2"))
    c = configuration_candidates(
        RECT, "straight:30", "none", scene, variants, min_mass=0.05, window_deg=5.0, merge_deg=2.0, max_candidates=8
    )
    base, _ = variant_pmf(RECT, "straight:30", "none", scene, variants[0])
    assert c.positions.size >= 1
    # every candidate of the base variant holds its base mass, and together the modes hold the base PMF
    assert c.masses[:, 0].sum() == pytest.approx(1.0, abs=1e-9)
    for p, m in zip(c.positions, c.masses[:, 0], strict=True):
        assert base[int(p)] > 0 or m == 0
    # loc2 alone has no fence: the initial yaw is uniform, every window of 11 bins holds 11/360
    assert c.pmfs[1] == pytest.approx(np.full(BINS, 1.0 / BINS))
    assert c.masses[:, 1] == pytest.approx(np.full(c.positions.size, 11.0 / BINS))
    assert c.ok.tolist() == pytest.approx([1.0, 1.0])


def test_the_frame_turns_the_candidates():
    scene = default_scene()
    kw = dict(min_mass=0.05, window_deg=5.0, merge_deg=2.0, max_candidates=8)
    a = configuration_candidates(RECT, "straight:30", "none", scene, (Variant("base"),), **kw)
    b = configuration_candidates(RECT, "straight:30", "none", scene, (Variant("base"),), frame_deg=30.0, **kw)
    assert np.sort(np.mod(a.positions + 30.0, 360.0)) == pytest.approx(np.sort(b.positions))


# ----------------------------------------------------------------------------------------------
# The mixture model
# ----------------------------------------------------------------------------------------------
def test_wrapped_gaussian_bins_sum_to_one_and_wrap():
    from feeder.learn.structured import wrapped_gaussian_bins

    g = wrapped_gaussian_bins(0.0, 2.0, BINS)  # centred on the seam
    assert g.sum() == pytest.approx(1.0)
    assert g[0] == pytest.approx(g[359])  # bin centres 0.5 and 359.5: both 0.5 from 0
    assert g[1] == pytest.approx(g[358])
    ratio = math.exp(-0.5 * (1.5**2 - 0.5**2) / 4.0)  # bins 1 and 0 at 1.5 and 0.5 deg
    assert g[1] / g[0] == pytest.approx(ratio)


def test_prior_logits_start_at_the_base_masses():
    from feeder.learn.structured import DIFFUSE, LOGIT_FLOOR, prior_logits

    cand, diff = prior_logits([[0.6, 0.3, 0.0]], [[True, True, False]])
    assert cand[0, :2] == pytest.approx(np.log([0.6 + LOGIT_FLOOR, 0.3 + LOGIT_FLOOR]))
    assert cand[0, 2] == -np.inf
    assert diff.shape == (1, len(DIFFUSE))
    assert diff[0, 0] == pytest.approx(math.log(0.1 + LOGIT_FLOOR))  # the analytic mass off the candidates
    assert diff[0, 1:] == pytest.approx(np.full(len(DIFFUSE) - 1, math.log(LOGIT_FLOOR)))


def test_torch_loss_is_the_metric():
    torch = pytest.importorskip("torch")
    from feeder.learn.structured import circular_w1_loss

    rng = np.random.default_rng(0)
    p = rng.dirichlet(np.ones(BINS), size=4)
    q = rng.dirichlet(np.ones(BINS), size=4)
    want = circular_w1(np.cumsum(q, axis=1), np.cumsum(p, axis=1)).mean()
    got = circular_w1_loss(torch.as_tensor(p), torch.as_tensor(np.cumsum(q, axis=1)))
    assert float(got) == pytest.approx(want, rel=1e-9)


def _toy_arrays(n=12, seed=0):
    """Configurations with two candidates 90 deg apart; the truth puts its mass on the first
    candidate when x > 0 and on the second otherwise, the analytic model always 50/50."""
    from feeder.learn.structured import wrapped_gaussian_bins

    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, 3))
    pos = np.tile([[40.5, 130.5]], (n, 1))
    masses = np.tile([[[0.5, 0.9, 0.1], [0.5, 0.1, 0.9]]], (n, 1, 1))  # (N, K=2, V=3)
    first = x[:, 0] > 0
    pmf = np.where(first[:, None], wrapped_gaussian_bins(40.5, 1.0, BINS), wrapped_gaussian_bins(130.5, 1.0, BINS))
    from feeder.learn.structured_data import candidate_features

    mask = np.ones((n, 2), dtype=bool)
    analytic = 0.5 * wrapped_gaussian_bins(40.5, 1.0, BINS) + 0.5 * wrapped_gaussian_bins(130.5, 1.0, BINS)
    return {
        "x": x,
        "pos": pos,
        "mask": mask,
        "masses": masses,
        "cf": candidate_features(masses, mask, 0.05),
        "base_mass": masses[:, :, 0],
        "pmf": pmf,
        "cdf": np.cumsum(pmf, axis=1),
        "analytic": np.tile(analytic, (n, 1)),
        "ok": np.where(first, 0.9, 0.2),
        "analytic_ok": np.full(n, 0.5),
        "wide_sigma_bins": 8.0,
    }


@pytest.mark.parametrize("kind", ["candidates", "variants"])
def test_an_untrained_network_answers_its_starting_mixture(kind):
    pytest.importorskip("torch")
    from feeder.learn.structured import (
        DIFFUSE,
        VARIANT_START_LOGIT,
        Fitted,
        NetSettings,
        diffuse_components,
        make_nets,
        predict,
        prior_logits,
        wrapped_gaussian_bins,
    )

    a = _toy_arrays()
    s = NetSettings(4, 4.0, 0.5, 1.5, 6.0, kind)
    net, ok = make_nets(3, a["cf"].shape[2], len(DIFFUSE), s, n_variants=3)
    mean = a["pmf"].mean(axis=0)
    pmf, _ = predict(Fitted(net, ok, 0, 0, math.nan, math.nan), a, np.arange(4), mean)
    diffuse = diffuse_components(a["analytic"][:4], mean, 8.0)
    g = wrapped_gaussian_bins(a["pos"][:4], np.full((4, 2), 1.5), BINS)
    if kind == "candidates":
        lc, ld = prior_logits(a["base_mass"][:4], a["mask"][:4])
        z = np.concatenate([lc, ld], axis=1)
        w = np.exp(z - z.max(axis=1, keepdims=True))
        w /= w.sum(axis=1, keepdims=True)
        wc, wd = w[:, :2], w[:, 2:]
    else:  # variant weights start at softmax(0, -4, -4 | -4 x 4); candidates get the variants' masses
        z = np.array([0.0] + [VARIANT_START_LOGIT] * (2 + len(DIFFUSE)))
        av = np.exp(z) / np.exp(z).sum()
        wc = np.tile(a["masses"][0] @ av[:3], (4, 1))
        wd = np.tile(av[3:], (4, 1))
    want = np.einsum("nk,nkb->nb", wc, g) + np.einsum("nc,ncb->nb", wd, diffuse)
    assert pmf == pytest.approx(want / want.sum(axis=1, keepdims=True), abs=1e-6)


@pytest.mark.parametrize("kind", ["candidates", "variants"])
def test_training_learns_which_candidate_the_inputs_choose(kind):
    pytest.importorskip("torch")
    from feeder.learn.structured import NetSettings, TrainSettings, fit, predict

    a = _toy_arrays(n=40)
    rows = np.arange(40)
    fitted = fit(
        a,
        rows[:30],
        rows[30:],
        rows[:30],
        rows[30:],
        a["pmf"][:30].mean(axis=0),
        NetSettings(8, 4.0, 0.5, 1.5, 6.0, kind),
        TrainSettings(0.03, 0.0, 300, 10, 100),
        seed=1,
    )
    pmf, ok = predict(fitted, a, rows[30:], a["pmf"][:30].mean(axis=0))
    before = circular_w1(a["cdf"][30:], np.cumsum(a["analytic"][30:], axis=1)).mean()
    after = circular_w1(a["cdf"][30:], np.cumsum(pmf, axis=1)).mean()
    assert before == pytest.approx(45.0, abs=1.0)  # half the mass 90 deg away
    assert after < before / 2
    assert np.abs(ok - a["ok"][30:]).mean() < 0.2
    assert fitted.steps > 0


@pytest.mark.parametrize("kind", ["candidates", "variants"])
def test_a_refit_on_the_fit_rows_for_the_kept_steps_is_the_early_stopped_network(kind):
    """structured.refit trains from the same initial weights with the same optimiser: on the same
    rows, for the steps early stopping kept, it reproduces the early-stopped networks exactly; on
    more rows it is another network; a negative step count is refused."""
    torch = pytest.importorskip("torch")
    from feeder.learn.structured import NetSettings, TrainSettings, fit, predict, refit

    a = _toy_arrays(n=40)
    rows, mean = np.arange(40), a["pmf"][:30].mean(axis=0)
    net, t = NetSettings(8, 4.0, 0.5, 1.5, 6.0, kind), TrainSettings(0.03, 0.0, 300, 10, 100)
    early = fit(a, rows[:30], rows[30:], rows[:30], rows[30:], mean, net, t, seed=1)
    assert early.steps > 0 and early.ok_steps > 0  # else the equality below proves nothing
    again = refit(a, rows[:30], rows[:30], mean, net, t, 1, early.steps, early.ok_steps)
    assert (again.steps, again.ok_steps) == (early.steps, early.ok_steps) and math.isnan(again.val_cw1)
    for mine, theirs in ((again.net, early.net), (again.ok_net, early.ok_net)):
        for (name, p), q in zip(mine.state_dict().items(), theirs.state_dict().values(), strict=True):
            assert torch.equal(p, q), name
    np.testing.assert_array_equal(predict(again, a, rows, mean)[0], predict(early, a, rows, mean)[0])
    more = refit(a, rows, rows, mean, net, t, 1, early.steps, early.ok_steps)
    assert not np.array_equal(predict(more, a, rows, mean)[0], predict(early, a, rows, mean)[0])
    with pytest.raises(FeederError, match="step counts"):
        refit(a, rows, rows, mean, net, t, 1, -1, 0)
    with pytest.raises(FeederError, match="rows to train on"):
        refit(a, rows[:0], rows, mean, net, t, 1, 10, 10)


def test_settings_are_checked():
    from feeder.learn.structured import NetSettings

    with pytest.raises(FeederError):
        NetSettings(4, 4.0, 2.0, 1.5, 6.0)  # sigma_min > sigma_init
    with pytest.raises(FeederError):
        NetSettings(4, 4.0, 0.5, 1.5, 6.0, "trees")


# ----------------------------------------------------------------------------------------------
# Protocol
# ----------------------------------------------------------------------------------------------
def test_seeds_and_part_picks_derive_from_ids():
    from feeder.learn.splits import derived_seed, pick_parts, resplit_rows

    assert derived_seed(39, "main", 1) == derived_seed(39, "main", 1) != derived_seed(39, "main", 2)
    parts = [f"p{i}" for i in range(20)]
    locked = pick_parts(parts, 0.15, 39, "locked")
    assert len(locked) == 3
    assert locked == pick_parts(parts[::-1] * 2, 0.15, 39, "locked")  # order and repeats do not matter
    # adding a part never unlocks a locked one that still ranks first
    more = pick_parts([*parts, "new"], 0.15, 39, "locked")
    assert len(more) == 3 and len(locked & more) >= 2
    with pytest.raises(FeederError):
        pick_parts(["only"], 0.5, 0, "val")
    test = resplit_rows(np.arange(100), 0.15, 7)
    assert test.size == 15 and np.all(np.diff(test) > 0)
    assert resplit_rows(np.arange(100), 0.15, 7).tolist() == test.tolist()


def test_unit_scores_and_comparison_by_hand():
    from feeder.learn.structured_protocol import comparison_table, unit_scores

    rows = []
    # part a: two configurations, part b: one; structured has two seeds
    for pred, seed, cw1s in (
        ("structured", 0, [1.0, 3.0, 5.0]),
        ("structured", 1, [3.0, 5.0, 7.0]),
        ("analytic_pmf", -1, [4.0, 6.0, 12.0]),
    ):
        for (part, cid), cw1 in zip([("a", "c1"), ("a", "c2"), ("b", "c1")], cw1s, strict=True):
            rows.append(
                {
                    "experiment": "unseen_groupkfold",
                    "repeat": 0,
                    "part": part,
                    "config_id": cid,
                    "split": "train",
                    "kept": True,
                    "predictor": pred,
                    "seed": seed,
                    "cw1": cw1,
                    "r2": 0.5,
                    "ok_true": 1.0,
                    "ok_pred": 0.9,
                }
            )
    rows.append(
        {**rows[-1], "config_id": "jam", "kept": False, "cw1": np.nan, "r2": np.nan, "ok_true": 0.0, "ok_pred": 0.5}
    )
    long = pd.DataFrame(rows)
    s = unit_scores(long, "unseen_groupkfold", "structured", "cw1")
    assert s.to_dict() == {"a": 3.0, "b": 6.0}  # a: (2 + 4) / 2 over its configurations
    ok = unit_scores(long, "unseen_groupkfold", "analytic_pmf", "ok_abs_err")
    assert ok.to_dict() == pytest.approx({"a": 0.1, "b": 0.3})  # b: (0.1 + 0.5) / 2, the jammed one counted
    t = comparison_table(long, {"resamples": 200, "level": 0.95, "seed": 0})
    assert set(t.model) == {"structured"}  # no averaged-seed rows in long: no such model
    row = t[(t.metric == "cw1") & (t.baseline == "analytic_pmf")].iloc[0]
    assert row.structured == pytest.approx(4.5) and row.baseline_value == pytest.approx(8.5)
    assert row["diff"] == pytest.approx(-4.0)  # a: 3 - 5, b: 6 - 12
    assert row.diff_low == pytest.approx(-6.0) and row.diff_high == pytest.approx(-2.0)  # both parts, either
    assert row.verdict == "better"


@pytest.mark.parametrize("kind", ["candidates", "variants"])
def test_an_untrained_network_started_on_the_analytic_pmf_answers_it(kind):
    pytest.importorskip("torch")
    from feeder.learn.structured import DIFFUSE, LOGIT_FLOOR, Fitted, NetSettings, make_nets, predict

    a = _toy_arrays()
    s = NetSettings(4, 4.0, 0.5, 1.5, 6.0, kind, "analytic")
    net, ok = make_nets(3, a["cf"].shape[2], len(DIFFUSE), s, n_variants=3)
    pmf, _ = predict(Fitted(net, ok, 0, 0, math.nan, math.nan, "analytic"), a, np.arange(4), a["pmf"].mean(axis=0))
    others = (2 if kind == "candidates" else 3) + len(DIFFUSE) - 1  # components at the floor
    off = others * LOGIT_FLOOR / (1.0 + others * LOGIT_FLOOR)  # their share of the mass
    assert circular_w1(np.cumsum(a["analytic"][:4], axis=1), np.cumsum(pmf, axis=1)).max() < 180.0 * off
    assert pmf == pytest.approx(a["analytic"][:4], abs=off)


def _toy_library(n_parts=10, per_part=4, seed=0):
    """:func:`_toy_arrays` spread over parts: GroupKFold folds by part, Main Train/Test rows, two
    Fences parts and one jammed (excluded) configuration."""
    n = n_parts * per_part
    a = _toy_arrays(n=n, seed=seed)
    part_idx = np.repeat(np.arange(n_parts), per_part)
    a["part"] = np.array([f"p{i}" for i in part_idx])
    cids = np.array(["straight30_none", "straight35_none", "straight45_none", "curved20_straight30", "straight60_none"])
    a["config_id"] = cids[np.tile(np.arange(per_part), n_parts)]
    split = np.where(np.tile(np.arange(per_part), n_parts) == 0, "test", "train")
    a["split"] = np.where(part_idx >= n_parts - 2, "fences", split)
    a["group_fold"] = part_idx % 3
    a["kept"] = np.ones(n, dtype=bool)
    a["kept"][1] = False  # jammed: no label, an ok share of 0
    a["pmf"][1] = 0.0
    a["cdf"] = np.cumsum(a["pmf"], axis=1)
    a["ok"][1] = 0.0
    return a


# a protocol small enough for the toy library: 2 seeds, 20 steps, both kinds, 2 Main splits
TOY_PROTOCOL = [
    "seeds=2",
    "train.max_steps=20",
    "train.patience_steps=10",
    "train.eval_every=5",
    "search=[{kind: variants, hidden: 4, weight_decay: 0.01},{kind: candidates, hidden: 4, weight_decay: 0.01}]",
    "protocol.main_repeats=2",
    "protocol.locked_fraction=0.2",
]


def test_the_protocol_keeps_locked_parts_out_until_the_end():
    pytest.importorskip("torch")
    from feeder.config import compose_config
    from feeder.learn.prior import grids
    from feeder.learn.structured_protocol import comparison_table, pick_parts, run_protocol

    overrides = [*TOY_PROTOCOL, "protocol.bootstrap.resamples=50"]
    cfg = compose_config("structured", overrides)
    a = _toy_library()
    long, choices = run_protocol(a, cfg, grids(compose_config("train")["prior"]))
    locked = pick_parts(a["part"], 0.2, int(cfg.seed), "locked")
    assert len(locked) == 2
    in_locked = long.part.isin(locked)
    assert set(long[in_locked].experiment) == {"unseen_locked"}  # scored once, nowhere else
    assert set(long[~in_locked].experiment) == {"unseen_groupkfold", "test", "fences"}
    assert list(choices.fit) == ["groupkfold:0", "groupkfold:1", "groupkfold:2", "main:0", "main:1", "locked"]
    parts = choices.set_index("fit")["train_parts"]
    assert parts["locked"] == 10 - len(locked) and (parts < 10 - len(locked) + 1).all()
    assert set(long[long.predictor == "structured"].seed) == {0, 1}
    # repeat 0 scores the dataset's own Test rows; the jammed row is scored on its ok share only
    test0 = long[(long.experiment == "test") & (long.repeat == 0) & (long.predictor == "analytic_pmf")]
    assert set(test0.config_id) == {"straight30_none"} and not test0.part.isin(locked).any()
    jam = long[(long.part == "p0") & (long.config_id == "straight35_none")]
    assert not jam.empty and jam.cw1.isna().all() and (jam.ok_true == 0.0).all()
    table = comparison_table(long, {"resamples": 50, "level": 0.95, "seed": 0})
    assert set(table.experiment) == {"unseen_groupkfold", "unseen_locked", "test", "fences"}
    assert set(table.verdict) <= {"better", "worse", "no clear difference"}
    # known parts are also compared with the part's gated neighbour; unseen parts have none
    assert set(table[table.baseline == "neighbour_gated"].experiment) == {"test", "fences"}
    assert set(choices.neighbours) == {int(cfg.model.neighbours)}
    # the seeds' averaged PMF (what the shipped file answers) is scored beside them: circular W1 is
    # convex in the CDF, so on every row it is no worse than the seeds' mean
    key = ["experiment", "repeat", "part", "config_id"]
    seeds = long[(long.predictor == "structured") & long.kept].groupby(key).cw1.mean()
    ensemble = long[(long.predictor == "structured_ensemble") & long.kept].set_index(key).cw1
    assert set(long[long.predictor == "structured_ensemble"].seed) == {-1}
    assert len(ensemble) == len(seeds) and (ensemble.reindex(seeds.index) <= seeds + 1e-9).all()
    assert set(table.model) == {"structured", "structured_ensemble"}
    assert table.groupby("model").size().nunique() == 1  # the same comparisons for both
    assert table[table.model == "structured_ensemble"].structured_seed_sd.isna().all()


def test_fits_run_at_once_give_the_same_rows_and_choices_in_the_same_order():
    pytest.importorskip("torch")
    from feeder.config import compose_config
    from feeder.learn.prior import grids
    from feeder.learn.structured_protocol import run_protocol

    overrides = TOY_PROTOCOL
    cfg = compose_config("structured", overrides)
    prior = grids(compose_config("train")["prior"])
    said = []
    one = run_protocol(_toy_library(), cfg, prior, workers=1)
    two = run_protocol(_toy_library(), cfg, prior, progress=said.append, workers=2)
    pd.testing.assert_frame_equal(one[0], two[0])  # every metric of every row, bit for bit
    pd.testing.assert_frame_equal(one[1].drop(columns="seconds"), two[1].drop(columns="seconds"))
    assert len(said) == 6 and said[0].startswith("groupkfold:0 (1 of 6 fits)") and said[-1].startswith("locked (6 of 6")
    for bad in (0, 1.5, "2", True):
        with pytest.raises(FeederError, match="train.workers must be an integer >= 1"):
            run_protocol(_toy_library(), cfg, prior, workers=bad)


def test_the_error_by_neighbour_distance_by_hand():
    """Rows at 5, 15 and 15 deg from their nearest label of the same types, one with only a label of
    its downstream fence type, one with none at all (left out); seeds averaged where scored so."""
    from feeder.learn.structured_protocol import check_edges, error_by_distance

    key = [("test", 0, "a", "c1"), ("test", 0, "a", "c2"), ("fences", 0, "b", "c3"), ("test", 1, "b", "c4")]
    key += [("fences", 0, "c", "c5")]
    rows = []
    for (experiment, repeat, part, cid), cw1 in zip(key, [1.0, 3.0, 5.0, 20.0, 50.0], strict=True):
        base = {"experiment": experiment, "repeat": repeat, "part": part, "config_id": cid, "kept": True}
        rows.append({**base, "predictor": "structured_ensemble", "seed": -1, "cw1": cw1})
        rows.append({**base, "predictor": "structured", "seed": 0, "cw1": cw1 + 100.0})  # not the one used
    rows.append({**rows[0], "experiment": "unseen_groupkfold"})  # not a Main fit's row
    long = pd.DataFrame(rows)
    distances = pd.DataFrame(
        [(*k, d, c) for k, d, c in zip(key, [5.0, 15.0, 15.0, np.inf, np.inf], [True, True, False, True, False])],
        columns=["experiment", "repeat", "part", "config_id", "neighbour_deg", "cross"],
    )
    t = error_by_distance(long, distances, [0, 10, 20])
    assert t.low_deg.tolist() == [0.0, 10.0, np.inf] and t.rows.tolist() == [1, 2, 1]
    assert t.mean_circular_w1_deg.tolist() == [1.0, 4.0, 20.0] and set(t.model) == {"structured_ensemble"}
    assert t.p90_circular_w1_deg[1] == pytest.approx(3.0 + 0.9 * 2.0)
    seeds = error_by_distance(long[long.predictor == "structured"], distances, [0, 10, 20])
    assert seeds.mean_circular_w1_deg.tolist() == [101.0, 104.0, 120.0]  # no averaged rows: the seeds'
    for bad in ([], [5, 10], [0, 10, 10], [0, float("inf")], "x"):
        with pytest.raises(FeederError, match="answer_errors.edges_deg"):
            check_edges(bad)


def test_two_runs_are_paired_on_the_units_both_scored():
    from feeder.learn.structured_protocol import paired_runs

    def rows(values):
        return pd.DataFrame(
            [
                {"experiment": "test", "repeat": 0, "part": p, "config_id": c, "kept": True, "predictor": "structured"}
                | {"seed": s, "cw1": v, "ok_pred": 1.0, "ok_true": 1.0}
                for (p, c, s), v in values.items()
            ]
        )

    run = rows({("a", "c1", 0): 4.0, ("a", "c1", 1): 6.0, ("b", "c2", 0): 3.0, ("d", "c9", 0): 99.0})
    base = rows({("a", "c1", 0): 2.0, ("b", "c2", 0): 3.0})
    pair = paired_runs(run, base, "test", "structured", {"resamples": 200, "level": 0.95, "seed": 0})
    assert pair["n"] == 2 and pair["run"] == 4.0 and pair["base"] == 2.5  # d/c9 is not in base: left out
    assert pair["diff"] == pytest.approx(1.5) and pair["diff_low"] == 0.0 and pair["diff_high"] == 3.0
    assert paired_runs(run, base, "fences", "structured", {"resamples": 10, "level": 0.95, "seed": 0}) is None
    # by part: configurations paired first (d/c9 still out), then each part's mean; a's two configurations count once
    run = rows({("a", "c1", 0): 4.0, ("a", "c3", 0): 8.0, ("b", "c2", 0): 3.0, ("d", "c9", 0): 99.0})
    base = rows({("a", "c1", 0): 2.0, ("a", "c3", 0): 2.0, ("b", "c2", 0): 2.0})
    pair = paired_runs(run, base, "test", "structured", {"resamples": 200, "level": 0.95, "seed": 0}, by_part=True)
    assert pair["n"] == 2 and pair["run"] == 4.5 and pair["base"] == 2.0
    assert pair["diff"] == pytest.approx(2.5) and pair["diff_low"] == 1.0 and pair["diff_high"] == 4.0


def test_neighbour_distances_follow_the_main_fits_training_rows():
    from feeder.config import compose_config
    from feeder.learn.structured_protocol import neighbour_distances, protocol_jobs

    cfg = compose_config("structured", TOY_PROTOCOL)
    a = _toy_library()
    d = neighbour_distances(a, cfg)
    jobs = [j for j in protocol_jobs(a, cfg)[0] if j[0] == "main"]
    assert len(d) == sum(int(m.sum()) for j in jobs for m in j[4].values())
    test0 = d[(d.experiment == "test") & (d.repeat == 0)].set_index("part")
    # repeat 0's Test rows are each part's straight30_none: nearest label straight35 (5 deg), but
    # p0's straight35 jammed (no label): straight45, 15 deg
    assert (test0.config_id == "straight30_none").all()
    assert test0.neighbour_deg.to_dict() == {p: (15.0 if p == "p0" else 5.0) for p in test0.index}
    assert not test0.cross.any()  # no other combination with a straight downstream fence
    fences = d[d.experiment == "fences"].set_index("config_id")
    # a Fences part has no training row: no neighbour of either kind
    assert np.isinf(fences.neighbour_deg).all() and not fences.cross.any()
    # a part with a label of the same downstream fence type in another combination has a cross neighbour
    a["config_id"] = np.where(a["config_id"] == "curved20_straight30", "straight20_curved30", a["config_id"])
    d = neighbour_distances(a, cfg)
    test0 = d[(d.experiment == "test") & (d.repeat == 0)].set_index("part")
    assert test0.cross.all()  # every part's straight20_curved30 is a training row


def test_from_rows_refuses_what_is_not_a_run_s_rows(tmp_path):
    from feeder.learn.structured_protocol import main

    with pytest.raises(FeederError, match="no such file"):
        main(["--from-rows", str(tmp_path / "none.csv"), "--out-dir", str(tmp_path)])
    pd.DataFrame({"part": ["a"]}).to_csv(tmp_path / "x.csv", index=False)
    with pytest.raises(FeederError, match="not a structured_rows.csv"):
        main(["--from-rows", str(tmp_path / "x.csv"), "--out-dir", str(tmp_path)])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.csv"]  # nothing written


def test_from_rows_writes_the_tables_of_a_run_s_rows(tmp_path):
    """--from-rows: the comparisons and the error by neighbour distance from rows alone; rows of
    other settings than the run's (another seed draws other splits) stop it in one line."""
    from factories import make_regression_dataset

    from feeder.config import compose_config
    from feeder.labels.dataset import load_dataset
    from feeder.learn.structured_data import split_arrays
    from feeder.learn.structured_protocol import main, neighbour_distances

    make_regression_dataset(tmp_path / "ds.npz")
    a = split_arrays(load_dataset(tmp_path / "ds.npz"))
    d = neighbour_distances(a, compose_config("structured", []))
    kept = dict(zip(zip(a["part"], a["config_id"]), a["kept"], strict=True))
    rows = []
    for i, r in enumerate(d.itertuples()):
        base = {"experiment": r.experiment, "repeat": r.repeat, "part": r.part, "config_id": r.config_id}
        base |= {"kept": kept[(r.part, r.config_id)], "ok_true": 1.0, "ok_pred": 1.0, "r2": 0.5}
        rows.append({**base, "predictor": "structured", "seed": 0, "cw1": float(i % 7)})
        rows.append({**base, "predictor": "analytic_pmf", "seed": -1, "cw1": float(i % 7) + 1.0})
    pd.DataFrame(rows).to_csv(tmp_path / "rows.csv", index=False)
    out = tmp_path / "out"
    assert (
        main(["--from-rows", str(tmp_path / "rows.csv"), "--dataset", str(tmp_path / "ds.npz"), "--out-dir", str(out)])
        == 0
    )
    assert sorted(p.name for p in out.iterdir()) == [
        "structured_by_distance.csv",
        "structured_protocol.csv",
        "structured_protocol.md",
    ]
    table = pd.read_csv(out / "structured_protocol.csv")
    assert set(table.baseline) == {"analytic_pmf"}
    np.testing.assert_allclose(table[table.metric == "cw1"]["diff"], -1.0)
    by = pd.read_csv(out / "structured_by_distance.csv")
    counted = (np.isfinite(d.neighbour_deg) | d.cross) & d.apply(lambda r: kept[(r.part, r.config_id)], axis=1)
    assert by.rows.sum() == counted.sum() and by.rows.sum() > 0
    with pytest.raises(FeederError, match="have no neighbour distance"):
        main(
            [
                "--from-rows",
                str(tmp_path / "rows.csv"),
                "--dataset",
                str(tmp_path / "ds.npz"),
                "--out-dir",
                str(tmp_path / "o2"),
                "seed=1",
            ]
        )
    assert not (tmp_path / "o2").exists()
    # an override right after the list option is still an override, not a second rows file
    with pytest.raises(FeederError, match="have no neighbour distance"):
        main(["--from-rows", str(tmp_path / "rows.csv"), "seed=1", "--dataset", str(tmp_path / "ds.npz")])
    with pytest.raises(FeederError, match="--from-rows needs a structured_rows.csv"):
        main(["--from-rows", "seed=1", "--dataset", str(tmp_path / "ds.npz"), "--out-dir", str(tmp_path / "o2")])
    assert not (tmp_path / "o2").exists()


def test_merge_runs_takes_each_kind_of_fit_from_the_last_run_holding_it():
    """merge_runs: a later run's kinds of fit replace an earlier run's, rows and choices alike; the
    other kinds stay; rows and choices that disagree on their kinds stop it in one line."""
    from feeder.learn.structured_protocol import merge_runs

    def run(tag, experiments, fits):
        rows = pd.DataFrame({"experiment": experiments, "repeat": 0, "cw1": tag})
        return rows, pd.DataFrame({"fit": fits, "val_cw1": tag})

    full = run(1.0, ["unseen_groupkfold", "test", "fences", "unseen_locked"], ["groupkfold:0", "main:0", "locked"])
    main_only = run(2.0, ["test", "fences", "test"], ["main:0", "main:1"])
    rows, choices, source = merge_runs([full, main_only])
    assert source == {"groupkfold": 0, "main": 1, "locked": 0}
    assert list(rows.experiment) == ["unseen_groupkfold", "test", "fences", "test", "unseen_locked"]
    assert list(rows.cw1) == [1.0, 2.0, 2.0, 2.0, 1.0]
    assert list(choices.fit) == ["groupkfold:0", "main:0", "main:1", "locked"]
    assert list(choices.val_cw1) == [1.0, 2.0, 2.0, 1.0]
    rows, choices, source = merge_runs([main_only, full])  # the last run holding a kind wins
    assert source == {"groupkfold": 1, "main": 1, "locked": 1} and list(rows.cw1) == [1.0] * 4
    with pytest.raises(FeederError, match="run 2: its rows hold the fits"):
        merge_runs([full, run(2.0, ["test"], ["main:0", "locked"])])


def test_from_rows_of_several_runs_writes_the_merged_run(tmp_path):
    """--from-rows A B: B's kinds of fit replace A's; the merged rows and choices are written beside
    the tables; a rows file without its choices stops it before anything is written."""
    from factories import make_regression_dataset

    from feeder.config import compose_config
    from feeder.labels.dataset import load_dataset
    from feeder.learn.structured_data import split_arrays
    from feeder.learn.structured_protocol import main, neighbour_distances

    make_regression_dataset(tmp_path / "ds.npz")
    a = split_arrays(load_dataset(tmp_path / "ds.npz"))
    d = neighbour_distances(a, compose_config("structured", []))
    kept = dict(zip(zip(a["part"], a["config_id"]), a["kept"], strict=True))
    test0 = d[(d.experiment == "test") & (d.repeat == 0)]
    unseen = test0.assign(experiment="unseen_groupkfold")  # the unseen parts' fits: run a alone
    unseen = pd.concat([unseen, test0.iloc[:1].assign(experiment="unseen_locked")], ignore_index=True)
    for name, shift in (("a", 0.0), ("b", 5.0)):
        rows = []
        for r in (pd.concat([d, unseen], ignore_index=True) if name == "a" else d).itertuples():
            base = {"experiment": r.experiment, "repeat": r.repeat, "part": r.part, "config_id": r.config_id}
            base |= {"kept": kept[(r.part, r.config_id)], "ok_true": 1.0, "ok_pred": 1.0, "r2": 0.5}
            rows.append({**base, "predictor": "structured", "seed": 0, "cw1": 1.0 + shift})
            rows.append({**base, "predictor": "analytic_pmf", "seed": -1, "cw1": 3.0})
        (tmp_path / name).mkdir()
        pd.DataFrame(rows).to_csv(tmp_path / name / "structured_rows.csv", index=False)
        fits = sorted({f"main:{r}" for r in d[d.experiment == "test"].repeat})
        if name == "a":
            fits = ["groupkfold:0", *fits, "locked"]
        pd.DataFrame({"fit": fits, "val_cw1": shift}).to_csv(tmp_path / name / "structured_choices.csv", index=False)
    args = ["--from-rows", str(tmp_path / "a" / "structured_rows.csv"), str(tmp_path / "b" / "structured_rows.csv")]
    args += ["--dataset", str(tmp_path / "ds.npz")]
    (tmp_path / "c").mkdir()
    pd.read_csv(tmp_path / "b" / "structured_rows.csv").to_csv(tmp_path / "c" / "structured_rows.csv", index=False)
    with pytest.raises(FeederError, match="no structured_choices.csv beside it"):
        main([*args[:2], str(tmp_path / "c" / "structured_rows.csv"), *args[3:], "--out-dir", str(tmp_path / "o")])
    assert not (tmp_path / "o").exists()
    assert main([*args, "--out-dir", str(tmp_path / "out")]) == 0
    merged = pd.read_csv(tmp_path / "out" / "structured_rows.csv")
    mine = merged[merged.predictor == "structured"]
    assert (mine[mine.experiment.isin(["test", "fences"])].cw1 == 6.0).all()
    assert (mine[~mine.experiment.isin(["test", "fences"])].cw1 == 1.0).all()
    assert len(merged) == 2 * (len(d) + len(unseen))
    choices = pd.read_csv(tmp_path / "out" / "structured_choices.csv")
    assert list(choices.val_cw1) == [0.0 if not f.startswith("main") else 5.0 for f in choices.fit]
    table = pd.read_csv(tmp_path / "out" / "structured_protocol.csv")
    diff = table[table.metric == "cw1"].groupby("experiment")["diff"].unique()
    assert diff["test"] == [3.0] and diff["fences"] == [3.0] and diff["unseen_groupkfold"] == [-2.0]


def test_cross_only_copies_train_fit_rows_again_without_their_own_combination():
    """model.cross_only_copies: a fit row with a neighbour of its own type combination and a cross
    neighbour also trains as a copy without the former; hide_same drops exactly those neighbours."""
    pytest.importorskip("torch")
    from omegaconf import OmegaConf

    from feeder.config import compose_config
    from feeder.learn.prior import grids
    from feeder.learn.structured_data import neighbour_rows, stack_rows
    from feeder.learn.structured_protocol import cross_only_copies, run_protocol

    a = _toy_library()
    a["config_id"] = np.where(a["config_id"] == "curved20_straight30", "straight20_curved30", a["config_id"])
    idx, dist = neighbour_rows(a, a["kept"], 2, 1)
    hid, hdist = neighbour_rows(a, a["kept"], 2, 1, hide_same=True)
    assert (hid[:, :2] == -1).all() and np.isinf(hdist[:, :2]).all()
    np.testing.assert_array_equal(hid[:, 2:], idx[:, 2:])  # the cross neighbour stays
    assert (idx[:, :2] >= 0).any() and (idx[:, 2:] >= 0).any()
    stacked = stack_rows({"part": a["part"], "x": a["x"], "bins": 360}, {"part": a["part"], "x": -a["x"], "bins": 7})
    assert stacked["x"].shape[0] == 2 * len(a["part"]) and stacked["bins"] == 360
    np.testing.assert_array_equal(stacked["x"][len(a["part"]) :], -a["x"])
    with pytest.raises(FeederError, match="different configurations"):
        stack_rows({"part": a["part"]}, {"part": a["part"][:3]})
    prior = grids(compose_config("train")["prior"])
    base = [*TOY_PROTOCOL, "protocol.fits=[main]"]
    off = run_protocol(a, compose_config("structured", base), prior)
    on = run_protocol(a, compose_config("structured", [*base, "model.cross_only_copies=true"]), prior)
    assert (off[1].cross_only_copies == 0).all() and (on[1].cross_only_copies > 0).all()
    # what the network trains on: each copy is its row with the same-combination neighbours missing
    from feeder.learn.structured_data import NEIGHBOUR_FEATURES
    from feeder.learn.structured_protocol import fit_protocol, protocol_jobs

    on_cfg = compose_config("structured", [*base, "model.cross_only_copies=true"])
    _, key, _, train, _ = protocol_jobs(a, on_cfg)[0][0]
    f = fit_protocol(a, train, on_cfg, key)
    n, rows, x = len(a["part"]), f["train_rows"], f["train_inputs"]["x"] * f["x_sd"] + f["x_mean"]
    copies, originals = rows[rows >= n], rows[rows >= n] - n
    width = len(NEIGHBOUR_FEATURES)
    first = x.shape[1] - (width * 3 + 2)  # the neighbour block: 2 same-combination, 1 cross, then 2 part inputs
    has = [first + width * j for j in range(3)]
    assert copies.size and (x[originals][:, has[0]] == 1).all()  # the rows copied have a same-combination label
    np.testing.assert_allclose(x[copies][:, has[:2]], 0.0, atol=1e-9)  # hidden in the copies
    np.testing.assert_allclose(x[copies][:, has[2]], x[originals][:, has[2]])  # the cross neighbour kept
    np.testing.assert_allclose(
        f["train_inputs"]["neighbour_pmf"][copies][:, 2], f["train_inputs"]["neighbour_pmf"][originals][:, 2]
    )
    assert (on[1].cross_only_copies < on[1].fit_rows).all()
    baselines = lambda long: long[~long.predictor.str.startswith("structured")].reset_index(drop=True)  # noqa: E731
    pd.testing.assert_frame_equal(baselines(off[0]), baselines(on[0]))
    for bad in ("yes", 1):
        with pytest.raises(FeederError, match="model.cross_only_copies"):
            cross_only_copies(OmegaConf.create({"model": {"cross_only_copies": bad}}))


def test_cross_only_reads_no_label_of_a_rows_own_combination_anywhere():
    """model.cross_only: in training, validation and scoring every row's same-combination
    neighbours are missing and its cross neighbour is kept; the baselines stay; a bad value or the
    combination with cross-only copies is refused."""
    pytest.importorskip("torch")
    from omegaconf import OmegaConf

    from feeder.config import compose_config
    from feeder.learn.prior import grids
    from feeder.learn.structured_data import NEIGHBOUR_FEATURES
    from feeder.learn.structured_protocol import cross_only, fit_protocol, pool_inputs, protocol_jobs, run_protocol

    a = _toy_library()
    a["config_id"] = np.where(a["config_id"] == "curved20_straight30", "straight20_curved30", a["config_id"])
    base = [*TOY_PROTOCOL, "protocol.fits=[main]"]
    off_cfg, on_cfg = compose_config("structured", base), compose_config("structured", [*base, "model.cross_only=true"])
    width = len(NEIGHBOUR_FEATURES)

    def has(x):  # the "has a label" inputs of the 2 same-combination neighbours and the cross one
        first = x.shape[1] - (width * 3 + 2)
        return x[:, [first + width * j for j in range(3)]]

    pool = a["kept"].copy()
    plain, hidden = pool_inputs(a, pool, off_cfg), pool_inputs(a, pool, on_cfg)
    np.testing.assert_array_equal(pool_inputs(a, pool, off_cfg, hide_same=True)["x"], hidden["x"])
    assert (has(plain["x"])[:, 0] == 1).any() and (has(hidden["x"])[:, :2] == 0).all()
    np.testing.assert_array_equal(has(hidden["x"])[:, 2], has(plain["x"])[:, 2])  # the cross neighbour kept
    assert (has(hidden["x"])[:, 2] == 1).any()
    _, key, _, train, _ = protocol_jobs(a, on_cfg)[0][0]
    f = fit_protocol(a, train, on_cfg, key)
    for inputs in (f["train_inputs"], f["scaled"]):  # what it trains on, and what its scored rows read
        x = inputs["x"] * f["x_sd"] + f["x_mean"]
        np.testing.assert_allclose(has(x)[:, :2], 0.0, atol=1e-9)
    assert f["choice"]["cross_only"] is True and fit_protocol(a, train, off_cfg, key)["choice"]["cross_only"] is False
    prior = grids(compose_config("train")["prior"])
    off, on = run_protocol(a, off_cfg, prior), run_protocol(a, on_cfg, prior)
    baselines = lambda long: long[~long.predictor.str.startswith("structured")].reset_index(drop=True)  # noqa: E731
    pd.testing.assert_frame_equal(baselines(off[0]), baselines(on[0]))
    for bad in ("yes", 1):
        with pytest.raises(FeederError, match="model.cross_only must be"):
            cross_only(OmegaConf.create({"model": {"cross_only": bad}}))
    with pytest.raises(FeederError, match="cannot be combined"):
        fit_protocol(
            a,
            train,
            compose_config("structured", [*base, "model.cross_only=true", "model.cross_only_copies=true"]),
            key,
        )
    assert cross_only(OmegaConf.create({"model": {}})) is False


def test_a_held_out_check_holds_out_the_fits_own_validation_parts_and_scores_them_both_ways():
    """feeder.learn.structured_heldout: the held-out parts are those the Main fit validates on; the
    fit on the rest never reads them; the held rows are scored as Test and as Fences rows (the
    latter without their own combination's labels); the Test-set flag and the paired table."""
    pytest.importorskip("torch")
    from feeder.config import compose_config
    from feeder.learn import structured_heldout as H
    from feeder.learn.prior import grids
    from feeder.learn.splits import derived_seed, pick_parts
    from feeder.learn.structured_protocol import fit_protocol, protocol_jobs

    a = _toy_library(n_parts=12)
    a["config_id"] = np.where(a["config_id"] == "curved20_straight30", "straight20_curved30", a["config_id"])
    cfg = compose_config("structured", [*TOY_PROTOCOL, "protocol.fits=[main]"])
    prior = grids(compose_config("train")["prior"])
    jobs = [j for j in protocol_jobs(a, cfg)[0] if j[0] == "main"]
    _, key, index, train, scored = jobs[1]
    held, inner, parts = H.held_out(a, train, cfg, key)
    assert parts == set(pick_parts(a["part"][train], 0.2, derived_seed(39, key), "val")) and parts
    assert not (held & inner).any() and ((held | inner) == train).all() and not (held & scored["test"]).any()
    assert fit_protocol(a, train, cfg, key)["choice"]["val_parts"] == len(parts)
    f = fit_protocol(a, inner, cfg, f"{key}:check")
    as_test = H.score_held(a, cfg, f, held, inner, "test", index, prior)
    as_fences = H.score_held(a, cfg, f, held, inner, "fences", index, prior)
    idx = set(zip(a["part"][held], a["config_id"][held], strict=True))
    for rows, name in ((as_test, "test"), (as_fences, "fences")):
        assert set(zip(rows.part, rows.config_id, strict=True)) <= idx and (rows.experiment == name).all()
        assert set(rows.predictor) == {H.STRUCTURED, H.ENSEMBLE}
    assert not np.allclose(as_test.cw1.to_numpy(), as_fences.cw1.to_numpy())  # the hidden labels count
    rows = pd.concat(
        [
            as_test.assign(arm="a"),
            as_fences.assign(arm="a"),
            as_test.assign(arm="b"),
            as_fences.assign(arm="b", cw1=as_fences.cw1 + 1.0),
        ]
    )
    rows = H.with_test_flag(rows, a, cfg)
    other_tests = {
        (p, c) for j in jobs for p, c in zip(a["part"][j[4]["test"]], a["config_id"][j[4]["test"]], strict=True)
    }
    assert list(rows.in_a_test_set) == [(p, c) in other_tests for p, c in zip(rows.part, rows.config_id, strict=True)]
    table = H.arm_comparisons(rows, dict(cfg.protocol.bootstrap), "b", "a").set_index(["rows", "scored_as", "model"])
    for unit in ("configuration", "part"):
        mine = table[table.unit == unit]
        assert mine.loc[("every held-out row", "fences", H.STRUCTURED)]["diff"] == pytest.approx(1.0)
        assert mine.loc[("every held-out row", "test", H.STRUCTURED)]["diff"] == 0
    n = table.loc[("every held-out row", "fences", H.STRUCTURED)].set_index("unit").n
    assert n["part"] == len(set(as_fences.part)) < n["configuration"]


def test_without_own_label_marks_rows_whose_part_has_no_kept_label_of_their_combination():
    from feeder.learn.structured_protocol import without_own_label

    ids = ["straight30_none", "straight40_none", "straight20_curved30", "straight30_none", "curved20_none"]
    a = {"part": np.array(["p", "p", "p", "q", "q"]), "config_id": np.array(ids)}
    a["kept"] = np.array([True, True, True, False, True])
    pool = np.array([True, False, False, True, True])
    # p/straight40 reads p/straight30; p's two-fence row and q/straight30 (its own row unkept) read
    # nothing; a row is never its own neighbour (q/curved20)
    assert without_own_label(a, pool, np.arange(5)).tolist() == [True, False, True, True, True]


def test_the_fences_specialist_answers_the_rows_without_their_own_combination_and_nothing_else():
    """model.fences_specialist: in a Main fit the rows with no label of their own combination (every
    Fences row) are the cross_only network's, fitted under its own key; every other row and every
    baseline is the run without it, to the bit; the choice carries the specialist's; bad values,
    the combination with cross_only and fit-structured are refused."""
    pytest.importorskip("torch")
    from omegaconf import OmegaConf

    from feeder.config import compose_config
    from feeder.learn.prior import grids
    from feeder.learn.structured_protocol import (
        cross_only,
        cross_only_copies,
        fences_specialist,
        fit_protocol,
        protocol_jobs,
        run_protocol,
        score_rows,
        specialist_cfg,
        without_own_label,
    )

    a = _toy_library(n_parts=12)
    a["config_id"] = np.where(a["config_id"] == "curved20_straight30", "straight20_curved30", a["config_id"])
    base = [*TOY_PROTOCOL, "protocol.fits=[main]", "blend.weights=[1.0]"]  # the networks alone
    off_cfg = compose_config("structured", [*base, "model.fences_specialist=false"])
    on_cfg = compose_config("structured", [*base, "model.fences_specialist=true"])
    assert fences_specialist(compose_config("structured", base))  # the default since stop 60
    prior = grids(compose_config("train")["prior"])
    off, on = run_protocol(a, off_cfg, prior), run_protocol(a, on_cfg, prior)
    _, key, index, train, scored = protocol_jobs(a, on_cfg)[0][0]
    fences = np.flatnonzero(scored["fences"])
    assert without_own_label(a, train, fences).all() and not without_own_label(a, train, scored["test"]).any()
    spec = fit_protocol(a, train, specialist_cfg(on_cfg), f"{key}:specialist")
    assert spec["choice"]["cross_only"] is True
    want = pd.DataFrame(score_rows(a, spec, fences, "fences", index, prior))
    want = want[want.predictor.str.startswith("structured")]
    got = on[0][(on[0].experiment == "fences") & (on[0].repeat == index) & on[0].predictor.str.startswith("structured")]
    np.testing.assert_array_equal(got.cw1.to_numpy(), want.cw1.to_numpy())
    cols = ["experiment", "repeat", "part", "config_id", "predictor", "seed"]
    off_rows, on_rows = (r[0].sort_values(cols).reset_index(drop=True) for r in (off, on))
    routed = set()  # (experiment, repeat, part, config_id) of the rows without their own combination's labels
    for _, _, r, t, sc in protocol_jobs(a, on_cfg)[0]:
        for experiment, mask in sc.items():
            idx = np.flatnonzero(mask)
            idx = idx[without_own_label(a, t, idx)]
            routed |= {(experiment, r, p, c) for p, c in zip(a["part"][idx], a["config_id"][idx], strict=True)}
    assert any(k[0] == "test" for k in routed)  # a resplit Test row of a type combination its part has once
    keys = zip(on_rows.experiment, on_rows.repeat, on_rows.part, on_rows.config_id, strict=True)
    theirs = on_rows.predictor.str.startswith("structured") & np.array([k in routed for k in keys])
    pd.testing.assert_frame_equal(on_rows[~theirs], off_rows[~theirs])
    assert not np.allclose(on_rows[theirs].cw1.to_numpy(), off_rows[theirs].cw1.to_numpy())
    assert on[1].specialist_cross_only.all() and "specialist_val_cw1" not in off[1]
    for bad in ("yes", 1):
        with pytest.raises(FeederError, match="model.fences_specialist must be"):
            fences_specialist(OmegaConf.create({"model": {"fences_specialist": bad}}))
    both = compose_config("structured", [*base, "model.fences_specialist=true", "model.cross_only=true"])
    assert not fences_specialist(both)  # cross_only: every row is the specialist's already
    copies = compose_config("structured", [*base, "model.cross_only_copies=true"])
    assert not cross_only_copies(specialist_cfg(copies)) and cross_only(specialist_cfg(copies))


def test_held_out_combinations_takes_one_two_fence_combination_of_each_drawn_training_part():
    """feeder.learn.structured_heldout.held_out_combinations, by hand: every training row of one
    two-fence combination per drawn part, none of another part, combination or split; parts with
    no two-fence row are never drawn; the draw is the key's; a fraction outside (0, 1] is refused."""
    from omegaconf import OmegaConf

    from feeder.learn import structured_heldout as H

    cfg = OmegaConf.create({"seed": 39})
    ids = ["straight30_none", "straight20_curved30", "straight25_curved30", "curved20_straight30", "curved20_curved40"]
    part = np.repeat([f"p{i}" for i in range(6)], len(ids))
    a = {"part": part, "config_id": np.tile(ids, 6)}
    a["config_id"][part == "p5"] = "straight30_none"  # no two-fence row: never drawn
    train = part != "p4"  # p4 is no training part
    train[2] = False  # p0's straight25_curved30 is not a training row: never held
    held, inner, chosen = H.held_out_combinations(a, train, cfg, "main:0")
    assert set(chosen) == {"p0", "p1", "p2", "p3"}
    assert not (held & inner).any() and ((held | inner) == train).all()
    combo = np.array(["_".join(H.fence_key(c)[0]) for c in a["config_id"]])
    for p, c in chosen.items():
        assert c in {"straight_curved", "curved_straight", "curved_curved"}
        np.testing.assert_array_equal(held[part == p], train[part == p] & (combo[part == p] == c))
    assert not held[part == "p5"].any() and not held[part == "p4"].any() and not held[2]
    assert H.held_out_combinations(a, train, cfg, "main:0")[2] == chosen  # the key's draw
    draws = {tuple(sorted(H.held_out_combinations(a, train, cfg, f"main:{k}")[2].items())) for k in range(8)}
    assert len(draws) > 1  # other keys draw other combinations
    half = H.held_out_combinations(a, train, cfg, "main:0", fraction=0.5)[2]
    assert len(half) == 2 and set(half) <= set(chosen)
    for bad in (0.0, 1.5):
        with pytest.raises(FeederError, match="fraction of parts"):
            H.held_out_combinations(a, train, cfg, "main:0", fraction=bad)


def test_held_out_combinations_scored_as_fences_rows_read_their_parts_other_combinations():
    """A fit without the held combinations; its held rows, scored as Fences rows from the whole
    training pool, read their part's labels of other combinations (the cross neighbour), never
    their own combination's, unlike the held rows alone."""
    pytest.importorskip("torch")
    from feeder.config import compose_config
    from feeder.learn import structured_heldout as H
    from feeder.learn.prior import grids
    from feeder.learn.structured_data import NEIGHBOUR_FEATURES
    from feeder.learn.structured_protocol import fit_protocol, protocol_jobs

    a = _toy_library(n_parts=12)
    a["config_id"] = np.where(a["config_id"] == "curved20_straight30", "straight20_curved30", a["config_id"])
    cfg = compose_config("structured", [*TOY_PROTOCOL, "protocol.fits=[main]"])
    _, key, index, train, _ = [j for j in protocol_jobs(a, cfg)[0] if j[0] == "main"][0]
    held, inner, chosen = H.held_out_combinations(a, train, cfg, key)
    assert held.any() and set(chosen.values()) == {"straight_curved"}
    f = fit_protocol(a, inner, cfg, f"{key}:check")
    assert not np.isin(f["train_rows"], np.flatnonzero(held)).any()
    width = len(NEIGHBOUR_FEATURES)
    first = f["scaled"]["x"].shape[1] - (width * 3 + 2)
    read = H.pool_inputs(a, train, cfg, hide_same=True)["x"][held]
    assert (read[:, [first, first + width]] == 0).all() and (read[:, first + 2 * width] == 1).all()
    prior = grids(compose_config("train")["prior"])
    as_fences = H.score_held(a, cfg, f, held, inner, "fences", index, prior, pool=train)
    alone = H.score_held(a, cfg, f, held, inner, "fences", index, prior)
    assert set(zip(as_fences.part, as_fences.config_id, strict=True)) == set(
        zip(a["part"][held & a["kept"]], a["config_id"][held & a["kept"]], strict=True)
    )
    assert not np.allclose(as_fences.cw1.to_numpy(), alone.cw1.to_numpy())  # the part's other labels count


def test_a_refit_trains_each_seed_on_the_validation_parts_too_and_keeps_the_baselines():
    """train.refit: the choice and each seed's step counts are early stopping's; the networks then
    train on every training row (validation parts included), whose inputs see every training row;
    every baseline stays; a bad value or a refit with cross-only copies is refused."""
    torch = pytest.importorskip("torch")
    from omegaconf import OmegaConf

    from feeder.config import compose_config
    from feeder.learn.prior import grids
    from feeder.learn.structured_protocol import fit_protocol, protocol_jobs, refit_on, run_protocol

    prior = grids(compose_config("train")["prior"])
    base = [*TOY_PROTOCOL, "protocol.fits=[main]", "blend.weights=[1.0]"]  # the networks alone
    off_cfg, on_cfg = compose_config("structured", base), compose_config("structured", [*base, "train.refit=true"])
    off, on = run_protocol(_toy_library(), off_cfg, prior), run_protocol(_toy_library(), on_cfg, prior)
    a, b = off[1].set_index("fit"), on[1].set_index("fit")
    assert (a.refit_rows == 0).all() and (b.refit_rows == b.fit_rows + b.val_rows).all()
    for col in ("kind", "hidden", "steps", "ok_steps", "val_cw1", "val_ok_mae"):
        assert (a[col] == b[col]).all(), col  # the choice is early stopping's, as without the refit
    baselines = lambda long: long[~long.predictor.str.startswith("structured")].reset_index(drop=True)  # noqa: E731
    pd.testing.assert_frame_equal(baselines(off[0]), baselines(on[0]))
    mine = lambda long: long[long.predictor == "structured"].cw1.to_numpy()  # noqa: E731
    assert not np.allclose(mine(off[0]), mine(on[0]))
    lib = _toy_library()
    _, key, _, train, _ = protocol_jobs(lib, on_cfg)[0][0]
    f = fit_protocol(lib, train, on_cfg, key)
    np.testing.assert_array_equal(f["train_rows"], np.flatnonzero(train & lib["kept"]))
    x = f["train_inputs"]["x"][np.flatnonzero(train)]
    np.testing.assert_allclose(x.mean(axis=0), 0.0, atol=1e-9)  # scaled on the rows it trains on
    np.testing.assert_allclose(f["mean_pmf"], lib["pmf"][train & lib["kept"]].mean(axis=0))
    assert all(math.isnan(s.val_cw1) for s in f["fits"])
    # the early-stopped seeds a refit starts from are the fit without it, and each refit trains for its own seed's steps
    off_fit = fit_protocol(lib, train, off_cfg, key)
    for mine, theirs in zip(f["early"]["fits"], off_fit["fits"], strict=True):
        for (name, p), q in zip(mine.net.state_dict().items(), theirs.net.state_dict().values(), strict=True):
            assert torch.equal(p, q), name
    for k in ("x_mean", "x_sd", "mean_pmf"):
        np.testing.assert_array_equal(f["early"][k], off_fit[k])
    assert [(s.steps, s.ok_steps) for s in f["fits"]] == [(s.steps, s.ok_steps) for s in off_fit["fits"]]
    for bad in ("yes", 1):
        with pytest.raises(FeederError, match="train.refit"):
            refit_on(OmegaConf.create({"train": {"refit": bad}, "model": {}}))
    with pytest.raises(FeederError, match="cannot be combined"):
        fit_protocol(
            lib, train, compose_config("structured", [*base, "train.refit=true", "model.cross_only_copies=true"]), key
        )
    assert refit_on(OmegaConf.create({"train": {}, "model": {}})) is False


def test_a_learning_curve_trains_on_fewer_parts_and_keeps_validation_and_baselines():
    """protocol.fit_part_fraction < 1: the network of a fit trains on fewer parts; its validation
    parts, its scored rows' neighbours and every baseline stay as at 1."""
    pytest.importorskip("torch")
    from omegaconf import OmegaConf

    from feeder.config import compose_config
    from feeder.learn.prior import grids
    from feeder.learn.structured_protocol import fit_part_fraction, run_protocol, unused_parts

    prior = grids(compose_config("train")["prior"])
    base = [*TOY_PROTOCOL, "protocol.fits=[main]", "blend.weights=[1.0]"]  # the networks alone
    whole = run_protocol(_toy_library(), compose_config("structured", base), prior)
    half_cfg = compose_config("structured", [*base, "protocol.fit_part_fraction=0.5"])
    half = run_protocol(_toy_library(), half_cfg, prior)
    a, b = whole[1].set_index("fit"), half[1].set_index("fit")
    assert (a.unused_parts == 0).all() and (b.unused_parts > 0).all()
    assert (b.val_rows == a.val_rows).all() and (b.fit_rows < a.fit_rows).all()
    base = lambda long: long[long.predictor != "structured"].query("predictor != 'structured_ensemble'")  # noqa: E731
    pd.testing.assert_frame_equal(base(whole[0]).reset_index(drop=True), base(half[0]).reset_index(drop=True))
    # the scored rows' inputs (their neighbours among every training row) are the same, unscaled
    from feeder.learn.structured_protocol import fit_protocol, protocol_jobs

    lib = _toy_library()
    whole_cfg = compose_config("structured", [*TOY_PROTOCOL, "protocol.fits=[main]"])
    _, key, _, train, _ = protocol_jobs(lib, whole_cfg)[0][0]
    f1, f2 = fit_protocol(lib, train, whole_cfg, key), fit_protocol(lib, train, half_cfg, key)
    raw = lambda f: f["scaled"]["x"] * f["x_sd"] + f["x_mean"]  # noqa: E731
    np.testing.assert_allclose(raw(f1), raw(f2), atol=1e-9)
    np.testing.assert_array_equal(f1["scaled"]["neighbour_pmf"], f2["scaled"]["neighbour_pmf"])
    assert f2["train_rows"].size < f1["train_rows"].size
    parts = [f"p{i}" for i in range(10)]
    assert unused_parts(parts, 1.0, 3) == set() and unused_parts(parts, 0.5, 3) >= unused_parts(parts, 0.75, 3)
    assert len(unused_parts(parts, 0.5, 3)) == 5
    for bad in (0, -0.5, 1.5, "half"):
        with pytest.raises(FeederError, match="protocol.fit_part_fraction"):
            fit_part_fraction(OmegaConf.create({"protocol": {"fit_part_fraction": bad}}))
    assert fit_part_fraction(OmegaConf.create({"protocol": {}})) == 1.0


# ----------------------------------------------------------------------------------------------
# The part's own neighbouring labels
# ----------------------------------------------------------------------------------------------
NB_PARTS = np.array(["a", "a", "a", "b", "a"])
NB_CIDS = np.array(["straight30_none", "straight40_none", "straight35_none", "straight30_none", "curved20_none"])


def test_nearest_rows_keep_to_the_part_and_its_fence_types_and_never_pick_the_row_itself():
    from feeder.learn.structured_data import nearest_rows

    idx, dist = nearest_rows(NB_PARTS, NB_CIDS, np.ones(5, bool), np.arange(5), 2)
    assert idx.tolist() == [[2, 1], [2, 0], [0, 1], [-1, -1], [-1, -1]]  # row 2: a tie at 5 deg, lower index first
    assert dist[:3].tolist() == [[5.0, 10.0], [5.0, 10.0], [5.0, 5.0]]
    assert np.isinf(dist[3:]).all()
    pool = np.array([True, False, True, True, True])  # row 1 is not labelled for this fit
    idx, dist = nearest_rows(NB_PARTS, NB_CIDS, pool, np.array([0, 1]), 2)
    assert idx.tolist() == [[2, -1], [2, 0]] and dist[0, 1] == np.inf  # an unlabelled row still reads its neighbours


def test_cross_neighbours_share_the_downstream_fence_in_another_type_combination():
    from feeder.learn.structured_data import nearest_cross_rows

    parts = np.array(["a", "a", "a", "a", "a", "b"])
    cids = np.array(
        [
            "straight30_curved20",  # 0: its cross neighbours are straight|none and straight|straight rows
            "straight50_none",  # 1
            "straight35_straight40",  # 2
            "straight32_curved60",  # 3: the same combination as row 0, never a cross neighbour of it
            "none_straight30",  # 4: no Location 1 fence, no cross neighbour
            "straight30_none",  # 5: another part
        ]
    )
    idx, dist = nearest_cross_rows(parts, cids, np.ones(6, bool), np.arange(6), 2)
    assert idx.tolist() == [[2, 1], [2, 3], [3, 0], [2, 1], [-1, -1], [-1, -1]]
    assert dist[:4].tolist() == [[5.0, 20.0], [15.0, 18.0], [3.0, 5.0], [3.0, 18.0]]


def _nb_arrays():
    """Four 90-degree bins: every analytic PMF at bin 0, the labels one bin on per row."""
    n = 5
    analytic = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    pmf = np.eye(4)[[1, 2, 3, 0, 1]].astype(float)  # labels; row 3 (part b) agrees with its analytic PMF
    return {
        "part": NB_PARTS,
        "config_id": NB_CIDS,
        "kept": np.ones(n, bool),
        "analytic": analytic,
        "pmf": pmf,
        "ok": np.array([0.9, 0.8, 0.7, 0.6, 0.5]),
        "analytic_ok": np.full(n, 0.25),
    }


def test_the_neighbour_block_by_hand():
    from feeder.learn.structured_data import FAR_DEG, neighbour_block

    a = _nb_arrays()
    a["analytic"][2] = [0.0, 1.0, 0.0, 0.0]  # row 2's analytic PMF one bin (90 deg) on
    feats, pmfs = neighbour_block(a, np.ones(5, bool), 1, 10.0)
    has, dist, near, move, miss, ok, part_miss, has_part = feats.T
    assert has.tolist() == [1, 1, 1, 0, 0]
    assert dist.tolist() == pytest.approx([5 / 90, 5 / 90, 5 / 90, FAR_DEG / 90, FAR_DEG / 90])
    # rows 0 and 1 read row 2, whose analytic PMF lies 90 deg from theirs; row 2 reads row 0 (same analytic)
    assert near.tolist() == pytest.approx([math.exp(-0.5)] * 3 + [0.0, 0.0])
    assert move.tolist() == pytest.approx([1.0, 1.0, 1.0, 0.0, 0.0])
    # row 2's label (bin 3) lies 180 deg from its analytic PMF (bin 1); row 0's (bin 1) 90 deg from bin 0
    assert miss.tolist() == pytest.approx([2.0, 2.0, 1.0, 0.0, 0.0])
    assert ok.tolist() == pytest.approx([0.7, 0.7, 0.9, 0.25, 0.25])  # missing: the row's analytic ok mass
    # the part's other rows: label against analytic W1 over 90 deg is 1, 2, 2, -, 1 for rows 0, 1, 2, 3, 4
    expected = [(2 + 2 + 1) / 3, (1 + 2 + 1) / 3, (1 + 2 + 1) / 3, 0.0, (1 + 2 + 2) / 3]
    assert part_miss.tolist() == pytest.approx(expected)
    assert has_part.tolist() == [1, 1, 1, 0, 1]
    assert pmfs.shape == (5, 1, 4)
    read = [a["pmf"][2], a["pmf"][2], a["pmf"][0], a["analytic"][3], a["analytic"][4]]  # missing: the analytic PMF
    assert np.array_equal(pmfs[:, 0], np.stack(read))


def test_the_neighbour_block_reads_no_label_outside_its_pool():
    from feeder.learn.structured_data import neighbour_block

    a = _nb_arrays()
    pool = np.array([True, True, False, True, True])
    feats, pmfs = neighbour_block(a, pool, 2, 10.0)
    b = dict(a, pmf=a["pmf"].copy())
    b["pmf"][2] = [0.25, 0.25, 0.25, 0.25]  # a label outside the pool changes nothing
    feats_b, pmfs_b = neighbour_block(b, pool, 2, 10.0)
    assert np.array_equal(feats, feats_b) and np.array_equal(pmfs, pmfs_b)
    c = dict(a, kept=np.array([True, True, True, True, False]))  # an excluded row is never a neighbour
    assert not np.array_equal(
        neighbour_block(c, np.ones(5, bool), 2, 10.0)[0], neighbour_block(a, np.ones(5, bool), 2, 10.0)[0]
    )


def test_no_neighbours_leave_the_inputs_as_they_are():
    from feeder.learn.structured_data import with_neighbours

    a = _nb_arrays()
    assert with_neighbours(a, np.ones(5, bool), 0, 10.0) is a
    b = with_neighbours(dict(a, x=np.zeros((5, 3))), np.ones(5, bool), 2, 10.0)
    assert b["x"].shape == (5, 3 + 6 * 2 + 2) and b["neighbour_pmf"].shape == (5, 2, 4)
    c = with_neighbours(dict(a, x=np.zeros((5, 3))), np.ones(5, bool), 1, 10.0, cross=1)
    assert c["x"].shape == (5, 3 + 6 * 2 + 2) and c["neighbour_pmf"].shape == (5, 2, 4)
    with pytest.raises(FeederError, match="neighbour_near_deg"):
        with_neighbours(a, np.ones(5, bool), 2, 0.0)


@pytest.mark.parametrize("bad", [-1, 1.5, "two", True])
def test_a_bad_neighbour_count_is_refused(bad):
    from omegaconf import OmegaConf

    from feeder.learn.structured_protocol import neighbour_count

    with pytest.raises(FeederError, match="model.neighbours"):
        neighbour_count(OmegaConf.create({"model": {"neighbours": bad}}))
    with pytest.raises(FeederError, match="model.cross_neighbours"):
        neighbour_count(OmegaConf.create({"model": {"cross_neighbours": bad}}), "cross_neighbours")


def test_the_candidates_cache_round_trips_and_holds_each_array_once(tmp_path):
    import tracemalloc

    from feeder.learn.structured_data import read_candidates_cache, write_candidates_cache

    rng = np.random.default_rng(0)
    n, bins, n_var = 300, 360, 4
    cands = [
        (
            rng.uniform(0, 360, k),
            rng.uniform(size=(k, n_var)),
            rng.uniform(size=n_var),
            rng.normal(size=29),
            rng.dirichlet(np.ones(bins)),
        )
        for k in rng.integers(0, 6, n)
    ]
    path = tmp_path / "cands.npz"
    write_candidates_cache(path, "key-a", cands, n_var)
    assert (
        read_candidates_cache(path, "key-b") is None and read_candidates_cache(tmp_path / "none.npz", "key-a") is None
    )
    tracemalloc.start()
    back = read_candidates_cache(path, "key-a")
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert len(back) == n
    for a, b in zip(cands, back, strict=True):
        assert all(np.array_equal(u, v) for u, v in zip(a, b, strict=True))
    # one copy of each array (the analytic PMFs alone are n x bins x 8 = 0.86 MB), not one per row
    assert peak < 4 * n * bins * 8


def test_a_cache_that_disagrees_with_the_dataset_is_recomputed_not_blamed_on_it(tmp_path):
    """A cache written under other BLAS kernels (same key) is recomputed; only candidates computed
    here that still disagree with the dataset's push block stop the run."""
    from feeder.learn.structured_data import cached_candidates, read_candidates_cache, write_candidates_cache

    rng = np.random.default_rng(1)

    def rows(push):
        return [(np.array([10.0]), np.ones((1, 2)), np.ones(2), p, np.full(360, 1 / 360)) for p in push]

    push = rng.normal(size=(3, 29))
    stale = push.copy()
    stale[1, :4] += 1.0  # one configuration's exit turn came out otherwise
    path = tmp_path / "cands.npz"
    write_candidates_cache(path, "key", rows(stale), 2)
    said, calls = [], []

    def compute(push=push):
        calls.append(1)
        return rows(push)

    got = cached_candidates(path, "key", push[:2], compute, 2, said.append)  # the kept rows come first
    assert calls == [1] and "disagrees" in said[0]
    assert np.array_equal(np.stack([c[3] for c in got]), push)
    assert np.array_equal(np.stack([c[3] for c in read_candidates_cache(path, "key")]), push)  # rewritten
    assert cached_candidates(path, "key", push[:2], compute, 2) is not None and calls == [1]  # now read
    assert cached_candidates(path, "key", None, compute, 2) is not None and calls == [1]  # no push block: trusted
    with pytest.raises(FeederError, match="rebuild the dataset"):
        cached_candidates(tmp_path / "new.npz", "key", stale[:2], compute, 2)
    assert not (tmp_path / "new.npz").exists()  # nothing cached from a run that stopped


def test_an_untrained_variant_network_weighs_the_neighbours_as_their_start_logit_says():
    pytest.importorskip("torch")
    from feeder.learn.structured import (
        DIFFUSE,
        LOGIT_FLOOR,
        Fitted,
        NetSettings,
        make_nets,
        predict,
        wrapped_gaussian_bins,
    )

    a = _toy_arrays()
    n = len(a["x"])
    nb = np.stack([wrapped_gaussian_bins(200.5, 2.0, BINS), wrapped_gaussian_bins(300.5, 2.0, BINS)])
    a["neighbour_pmf"] = np.broadcast_to(nb, (n, 2, BINS)).copy()
    s = NetSettings(4, 4.0, 0.5, 1.5, 6.0, "variants", "analytic", neighbour_start_logit=0.0)
    net, ok = make_nets(3, a["cf"].shape[2], len(DIFFUSE) + 2, s, n_variants=3)
    pmf, _ = predict(Fitted(net, ok, 0, 0, math.nan, math.nan, "analytic"), a, np.arange(4), a["pmf"].mean(axis=0))
    others = 3 + len(DIFFUSE) - 1  # the variants and the other diffuse components, at the floor
    off = others * LOGIT_FLOOR / (3.0 + others * LOGIT_FLOOR)
    expected = (a["analytic"][:4] + nb[0] + nb[1]) / 3.0  # analytic and both neighbours at logit 0
    assert np.abs(pmf - expected).sum(axis=1).max() < 2 * off


def test_basin_owners_climb_to_their_peak_across_the_seam():
    from feeder.labels.metrics import basin_owners, resting_orientations

    p = np.array([0.3, 0.1, 0.05, 0.1, 0.2, 0.05, 0.0, 0.2])  # peaks at bins 0 and 4; bin 7 climbs to 0 over the seam
    # bin 2 climbs to its higher side (3, then 4); bin 6 to its higher side, 7, and on over the seam
    assert basin_owners(p).tolist() == [0, 0, 4, 4, 4, 4, 0, 0]
    assert [m for _, m in resting_orientations(p)] == pytest.approx([0.6, 0.4])


def test_basin_components_by_hand():
    from feeder.learn.structured_data import basin_components

    label = np.array([0.3, 0.1, 0.05, 0.1, 0.2, 0.05, 0.0, 0.2])  # basins {6, 7, 0, 1} 0.6 and {2..5} 0.4
    analytic = np.array([[0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0]])
    pmfs = np.stack([label, label])[:, None, :]
    idx = np.array([[1], [-1]])  # row 0 reads row 1; row 1 has no neighbour
    feats, comps, offsets = basin_components(pmfs, analytic, idx, 1)
    big = np.array([0.3, 0.1, 0, 0, 0, 0, 0, 0.2]) / 0.6
    assert np.allclose(comps[0, 0], big) and np.allclose(comps[0, 1], (label - 0.6 * big) / 0.4)
    assert offsets[0].tolist() == pytest.approx([math.log(0.6), math.log(0.4)])
    assert feats[0].tolist() == pytest.approx([0.6, 0.0, 0.5])  # its mass; the row's and the neighbour's analytic
    assert np.array_equal(comps[1], np.stack([analytic[1], analytic[1]])) and feats[1].tolist() == [0, 0, 0]
    # together the basins are the label again
    assert np.allclose((np.exp(offsets[0])[:, None] * comps[0]).sum(axis=0), label)


def test_an_untrained_network_answers_the_same_whether_the_neighbours_are_whole_or_in_basins():
    pytest.importorskip("torch")
    from feeder.learn.structured import DIFFUSE, Fitted, NetSettings, make_nets, predict, wrapped_gaussian_bins
    from feeder.learn.structured_data import basin_components

    a = _toy_arrays()
    n = len(a["x"])
    label = 0.7 * wrapped_gaussian_bins(200.5, 2.0, BINS) + 0.3 * wrapped_gaussian_bins(300.5, 2.0, BINS)
    whole = dict(a, neighbour_pmf=np.broadcast_to(label, (n, 1, BINS)).copy())
    _, comps, offsets = basin_components(whole["neighbour_pmf"], a["analytic"], np.zeros((n, 1), int), 1)
    split = dict(a, neighbour_pmf=comps, neighbour_offset=offsets)
    for kind in ("variants", "candidates"):
        s = NetSettings(4, 4.0, 0.5, 1.5, 6.0, kind, "analytic", neighbour_start_logit=0.0)
        answers = []
        for arrays, extra in ((whole, 1), (split, 2)):
            torch_seed = __import__("torch").manual_seed(0)
            assert torch_seed is not None
            net, ok = make_nets(3, a["cf"].shape[2], len(DIFFUSE) + extra, s, n_variants=3)
            fitted = Fitted(net, ok, 0, 0, math.nan, math.nan, "analytic")
            answers.append(predict(fitted, arrays, np.arange(4), a["pmf"].mean(axis=0))[0])
        assert np.abs(answers[0] - answers[1]).sum(axis=1).max() < 1e-5, kind


@pytest.mark.parametrize("bad", [-1, 1.5, True])
def test_a_bad_basin_count_is_refused(bad):
    from feeder.learn.structured_data import with_neighbours

    with pytest.raises(FeederError, match="model.neighbour_basins must be an integer >= 0"):
        with_neighbours(dict(_nb_arrays(), x=np.zeros((5, 3))), np.ones(5, bool), 1, 10.0, basins=bad)


def test_window_mass_wraps_around_the_seam():
    from feeder.learn.structured_data import window_mass

    p = np.array([[0.4, 0.1, 0.0, 0.0, 0.0, 0.0, 0.2, 0.3]])  # 8 bins of 45 deg, centres 22.5, 67.5, ...
    # around 0 deg within 30: the bins centred 22.5 and 337.5; within 70: 67.5 and 292.5 too
    assert window_mass(p, np.array([[0.0, 360.0]]), 30.0)[0].tolist() == pytest.approx([0.7, 0.7])
    assert window_mass(p, np.array([[0.0]]), 70.0)[0].tolist() == pytest.approx([1.0])
    assert window_mass(p, np.array([[180.0]]), 30.0)[0].tolist() == pytest.approx([0.0])


def test_neighbour_candidates_by_hand():
    from feeder.learn.structured_data import neighbour_candidates

    # 8 bins of 45 deg; row 0 reads row 1's label (basins: 0.6 around bin 0, centre 22.5; 0.4 around bin 4,
    # centre 202.5); row 1 has no neighbour
    label = np.array([0.3, 0.1, 0.05, 0.1, 0.2, 0.05, 0.0, 0.2])
    analytic = np.array([[0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0]])
    a = {
        "pos": np.array([[200.0], [10.0]]),  # row 0's one analytic candidate lies 2.5 deg from the label's second mode
        "mask": np.array([[True], [True]]),
        "masses": np.array([[[0.9, 0.8]], [[0.5, 0.4]]]),
        "base_mass": np.array([[0.9], [0.5]]),
        "cf": np.array([[[7.0]], [[8.0]]]),
        "analytic": analytic,
    }
    out = neighbour_candidates(a, np.stack([label, label])[:, None, :], np.array([[1], [-1]]), 2, 5.0, 30.0)
    # the first mode (22.5) is new; the second (202.5) merges with the candidate at 200
    assert out["pos"].shape == (2, 3) and out["mask"].tolist() == [[True, True, False], [True, False, False]]
    assert out["pos"][0, 1] == pytest.approx(22.5)
    assert out["masses"][0, 1].tolist() == [0.0, 0.0] and out["base_mass"][0, 1] == 0.0
    assert out["masses"][0, 0].tolist() == [0.9, 0.8]
    # features: the old one, the neighbour's mass within 30 deg, the row's analytic mass there, from a neighbour
    assert out["cf"][0, 0].tolist() == pytest.approx([7.0, 0.2, 1.0, 0.0])  # 200: only bin 4 (202.5)
    assert out["cf"][0, 1].tolist() == pytest.approx([0.0, 0.3, 0.0, 1.0])  # 22.5: only bin 0
    assert out["cf"][1, 0].tolist() == pytest.approx([8.0, 0.0, 0.5, 0.0])  # no neighbour: no neighbour mass
    assert not out["cf"][:, 2].any() and not out["cf"][1, 1].any()  # padding stays zero
    assert neighbour_candidates(a, np.zeros((2, 1, 8)), np.array([[1], [-1]]), 0, 5.0, 30.0) is a
    with pytest.raises(FeederError, match="model.neighbour_candidates must be an integer >= 0"):
        neighbour_candidates(a, np.zeros((2, 1, 8)), np.array([[1], [-1]]), -1, 5.0, 30.0)


def test_neighbour_candidates_leave_an_untrained_network_as_it_was():
    """New candidates start at the floor logit (start: analytic) and carry no variant masses, so an
    untrained network of either kind answers nearly as before (within the floor's share)."""
    pytest.importorskip("torch")
    from feeder.learn.structured import DIFFUSE, Fitted, NetSettings, make_nets, predict, wrapped_gaussian_bins
    from feeder.learn.structured_data import neighbour_candidates

    a = _toy_arrays()
    n = len(a["x"])
    label = 0.7 * wrapped_gaussian_bins(200.5, 2.0, BINS) + 0.3 * wrapped_gaussian_bins(300.5, 2.0, BINS)
    whole = dict(a, neighbour_pmf=np.broadcast_to(label, (n, 1, BINS)).copy())
    more = neighbour_candidates(whole, whole["neighbour_pmf"], np.zeros((n, 1), int), 2, 2.0, 5.0)
    assert more["mask"].sum() > whole["mask"].sum()
    for kind in ("variants", "candidates"):
        s = NetSettings(4, 4.0, 0.5, 1.5, 6.0, kind, "analytic", neighbour_start_logit=0.0)
        answers = []
        for arrays in (whole, more):
            __import__("torch").manual_seed(0)
            net, ok = make_nets(3, arrays["cf"].shape[2], len(DIFFUSE) + 1, s, n_variants=3)
            fitted = Fitted(net, ok, 0, 0, math.nan, math.nan, "analytic")
            answers.append(predict(fitted, arrays, np.arange(4), a["pmf"].mean(axis=0))[0])
        assert np.abs(answers[0] - answers[1]).sum(axis=1).max() < 0.02, kind


def test_start_grid_drops_pick_evenly_spread_start_yaws():
    from feeder.learn.structured_data import start_grid_drops

    design = {"n0": 8, "period_deg": 180.0, "offset_deg": 5.0}  # start yaws 5, 27.5, 50, ..., 162.5
    initial = np.array([5.0, 16.25, 27.5, 50.0, 72.5, 95.0, 117.5, 140.0, 162.5, 100.0])  # 16.25, 100: refined
    assert start_grid_drops(initial, design, 4).tolist() == [0, 3, 5, 7]  # j = 0, 2, 4, 6: 5, 50, 95, 140
    assert start_grid_drops(initial, design, 1).tolist() == [0]
    with pytest.raises(FeederError, match="start-grid yaw 50.000000 deg has no drop"):
        start_grid_drops(np.delete(initial, 3), design, 4)
    for bad in (0, 9):
        with pytest.raises(FeederError, match="model.drops must be an integer in 1..n0"):
            start_grid_drops(initial, design, bad)
    for bad_design, bad_initial in (({}, initial), (None, initial), (design, None)):
        with pytest.raises(FeederError, match="the adaptive design's start grid and initial yaws"):
            start_grid_drops(bad_initial, bad_design, 4)


def test_drops_label_turns_into_the_label_frame_and_copies_over_the_symmetry():
    from feeder.learn.structured_data import drops_label

    # two drops at 10 and 100 (part frame) of a part with period 180, label frame 30 (label = part + 30):
    # 40, 130, 220, 310 (a frame of -30 would give 340, 70, 160, 250)
    p = drops_label(np.array([10.2, 100.2]), 180.0, 30.0, 360, 0.0)
    assert np.flatnonzero(p).tolist() == [40, 130, 220, 310] and p.sum() == pytest.approx(1.0)
    assert p[40] == pytest.approx(0.25)
    q = drops_label(np.array([359.9]), 360.0, 0.0, 360, 2.0)  # smoothed across the seam
    assert q.sum() == pytest.approx(1.0) and q[0] == pytest.approx(q[358]) and q[0] > q[5]


def test_with_drops_adds_a_component_inputs_and_candidates():
    from feeder.learn.structured_data import with_drops

    a = _toy_arrays(n=4)
    bins = a["pmf"].shape[1]
    drop = np.zeros((4, bins))
    drop[[0, 1, 2], [250, 200, 131]] = 1.0  # rows' drops at 250.5, 200.5 (far from 40.5, 130.5) and 131.5 (merged)
    drop[3] = a["analytic"][3]  # row 3: no ok drop
    a = dict(a, drop_pmf=drop, drop_ok=np.array([1.0, 0.5, 0.25, 0.0]), drop_has=np.array([1.0, 1.0, 1.0, 0.0]))
    b = with_drops(a, 2, 2.0, 5.0)
    assert b["x"].shape == (4, 3 + 2) and b["x"][:, -2:].tolist() == [[1, 1], [0.5, 1], [0.25, 1], [0, 0]]
    assert b["neighbour_pmf"].shape == (4, 1, bins) and np.array_equal(b["neighbour_pmf"][:, 0], drop)
    assert b["mask"].sum(axis=1).tolist() == [3, 3, 2, 2]  # a new candidate per row's own drops, unless merged
    assert b["pos"][:2, 2].tolist() == pytest.approx([250.5, 200.5])
    assert b["cf"][0, 2, -3:].tolist() == pytest.approx([1.0, 0.0, 1.0])  # drop mass, analytic mass, new
    assert b["cf"][2, 1, -3:].tolist() == pytest.approx([1.0, b["cf"][2, 1, -2], 0.0])  # 131.5 lies by 130.5
    assert b["cf"][2, 1, -2] > 0.4
    c = with_drops(dict(a, neighbour_pmf=a["pmf"][:, None, :], neighbour_offset=np.ones((4, 1))), 0, 2.0, 5.0)
    assert c["neighbour_pmf"].shape == (4, 2, bins) and c["mask"].shape == a["mask"].shape  # no candidates
    assert c["neighbour_offset"].tolist() == [[1.0, 0.0]] * 4  # the drops' component starts at no offset


def test_drop_arrays_read_the_start_grid_of_each_simulation_file(tmp_path):
    import json

    from feeder.learn.structured_data import drop_arrays

    design = {"n0": 4, "period_deg": 360.0, "offset_deg": 10.0}  # start yaws 10, 100, 190, 280
    files = {
        ("p", "straight30_none"): (
            [10.0, 55.0, 100.0, 190.0, 280.0],
            [20.5, 0, 110.5, 200.5, 290.5],
            "ok jammed ok ok ok",
        ),
        ("p", "straight40_none"): ([10.0, 100.0, 190.0, 280.0], [0, 0, 0, 0], "jammed jammed jammed fell_off"),
    }
    for (part, cid), (initial, final, status) in files.items():
        (tmp_path / part).mkdir(exist_ok=True)
        np.savez(
            tmp_path / part / f"{cid}.npz",
            initial_yaw_deg=np.array(initial),
            final_yaw_deg=np.array(final, dtype=float),
            status=np.array(status.split()),
            meta=np.array(json.dumps({"design": design})),
        )
    arrays = {
        "part": np.array(["p", "p"]),
        "config_id": np.array(["straight30_none", "straight40_none"]),
        "frame_deg": np.array([0.0, 0.0]),
        "analytic": np.full((2, 360), 1 / 360),
    }
    out = drop_arrays(arrays, tmp_path, 2, 360, 0.0)  # yaws 10 and 190: the first's drops ended at 20.5, 200.5
    assert np.flatnonzero(out["drop_pmf"][0]).tolist() == [20, 200]
    assert out["drop_ok"].tolist() == [1.0, 0.0] and out["drop_has"].tolist() == [1.0, 0.0]
    assert np.array_equal(out["drop_pmf"][1], arrays["analytic"][1])  # no ok drop: the analytic PMF
    with pytest.raises(FeederError, match="straight30_none.npz: model.drops must be an integer in 1..n0"):
        drop_arrays(arrays, tmp_path, 5, 360, 0.0)


@pytest.mark.parametrize("bad", [-1, 1.5, "two", True])
def test_a_bad_drop_count_is_refused(bad):
    from omegaconf import OmegaConf

    from feeder.learn.structured_protocol import drop_count

    for key in ("drops", "drop_candidates", "neighbour_basins", "neighbour_candidates"):
        with pytest.raises(FeederError, match=f"model.{key} must be an integer >= 0"):
            drop_count(OmegaConf.create({"model": {key: bad}}), key)
    assert drop_count(OmegaConf.create({"model": {}})) == 0


@pytest.mark.parametrize("bad", [-1, 1.5, True])
def test_a_bad_neighbour_candidate_count_is_refused_before_any_work(bad, tmp_path):
    from feeder.learn.structured_protocol import main

    with pytest.raises(FeederError, match="model.neighbour_candidates must be an integer >= 0"):
        main(["--dataset", str(tmp_path / "missing.npz"), f"model.neighbour_candidates={bad}"])


def test_the_protocol_reads_each_configurations_drops_and_compares_with_them():
    """With drops read (the truth itself here, so that a network that uses them must learn to), every
    experiment compares the structured predictor with the drops' own label, and the fits record it."""
    pytest.importorskip("torch")
    from feeder.config import compose_config
    from feeder.learn.prior import grids
    from feeder.learn.structured_protocol import DROPS, comparison_table, run_protocol

    cfg = compose_config("structured", [*TOY_PROTOCOL, "protocol.bootstrap.resamples=50", "model.drops=4"])
    a = _toy_library()
    n = len(a["part"])
    a = dict(a, drop_pmf=np.where(a["kept"][:, None], a["pmf"], a["analytic"]), drop_ok=a["ok"], drop_has=np.ones(n))
    long, choices = run_protocol(a, cfg, grids(compose_config("train")["prior"]))
    assert set(long[long.predictor == DROPS].experiment) == {"unseen_groupkfold", "unseen_locked", "test", "fences"}
    assert (long[(long.predictor == DROPS) & long.kept].cw1 < 1e-9).all()  # the drops' label is the truth here
    table = comparison_table(long, {"resamples": 50, "level": 0.95, "seed": 0})
    assert set(table[table.baseline == DROPS].experiment) == {"unseen_groupkfold", "unseen_locked", "test", "fences"}
    assert set(choices.drops) == {4}


# the downstream fence alone: 40 for initial yaws in [0, 135) and [315, 360), 220 in [135, 315)
# (agreeing intervals keep their basin, disagreeing ones take the nearer sample's)
DOWNSTREAM = ([40.0, 40.0, 220.0, 220.0], None)


def test_compose_maps_by_hand():
    from feeder.learn.structured_data import compose_maps

    down = grid_map(*DOWNSTREAM)
    pmf, share = compose_maps(grid_map([100.0] * 4), down, 5.0, 360, 0.0, yaws=720)
    assert share == 1.0 and pmf[45] == pytest.approx(1.0)  # every yaw rests at 100, then 40; the frame turns it by 5
    # upstream: ok at 100 for [0, 45) and [315, 360), ok at 200 for [135, 225), jammed elsewhere
    up = grid_map([100.0, 0.0, 200.0, 0.0], ["ok", "jammed", "ok", "jammed"])
    pmf, share = compose_maps(up, down, 0.0, 360, 0.0, yaws=720)
    assert share == pytest.approx(0.5) and pmf[40] == pytest.approx(0.5) and pmf[220] == pytest.approx(0.5)
    smooth, _ = compose_maps(up, down, 0.0, 360, 1.0, yaws=720)
    assert smooth.sum() == pytest.approx(1.0) and 0 < smooth[40] < 0.5 and smooth[41] > 0  # smoothed as labels are
    none, share = compose_maps(grid_map([0.0] * 4, ["jammed"] * 4), down, 0.0, 360, 0.0, yaws=720)
    assert none is None and share == 0.0
    with pytest.raises(FeederError, match="yaws must be >= 1"):
        compose_maps(up, down, 0.0, 360, 0.0, yaws=0)


def test_one_fence_rows_pick_each_fence_alone_of_its_type_nearest_in_angle():
    from feeder.learn.structured_data import fence_alone, one_fence_rows

    assert [fence_alone(c) for c in ("none_curved30", "straight40_none", "straight40_curved30", "none_none")] == [
        (2, "curved"),
        (1, "straight"),
        None,
        None,
    ]
    parts = ["p"] * 7 + ["q"]
    cids = [
        "curved20_straight30",  # 0: two fences
        "none_straight25",  # 1: the upstream fence alone, 5 deg away
        "none_straight35",  # 2: 5 deg away too (the lower index wins)
        "none_curved30",  # 3: another type
        "curved40_none",  # 4: the downstream fence alone, 20 deg away
        "curved10_none",  # 5: 10 deg away
        "straight30_none",  # 6: another type
        "curved20_none",  # 7: another part
    ]
    pool = np.ones(8, dtype=bool)
    up, d_up, down, d_down = one_fence_rows(parts, cids, pool, np.arange(8))
    assert (up[0], d_up[0], down[0], d_down[0]) == (1, 5.0, 5, 10.0)
    assert (up[1:] == -1).all() and (down[1:] == -1).all() and np.isinf(d_up[1:]).all()  # one fence or none
    pool[[1, 5]] = False
    up, d_up, down, d_down = one_fence_rows(parts, cids, pool, np.array([0]))
    assert (up[0], down[0], d_down[0]) == (2, 4, 20.0)
    pool[2] = False
    assert one_fence_rows(parts, cids, pool, np.array([0]))[0][0] == -1


def _composed_arrays():
    from feeder.learn.structured_data import one_fence_maps  # noqa: F401 (the entry it builds, by hand here)

    bins = 360
    analytic = np.full((4, bins), 1.0 / bins)
    return {
        "part": np.array(["p", "p", "p", "q"]),
        "config_id": np.array(["curved20_straight30", "none_straight30", "curved20_none", "curved20_straight30"]),
        "kept": np.ones(4, dtype=bool),
        "frame_deg": np.zeros(4),
        "analytic": analytic,
        "analytic_ok": np.array([0.9, 0.8, 0.7, 0.6]),
        "x": np.zeros((4, 2)),
        "composed_maps": {
            "maps": {1: grid_map([100.0] * 4), 2: grid_map(*DOWNSTREAM)},
            "sigma_bins": 0.0,
            "memo": {},
        },
    }


def test_the_composed_block_by_hand():
    from feeder.learn.structured_data import FAR_DEG, composed_block

    a = _composed_arrays()
    feats, pmfs = composed_block(a, np.ones(4, dtype=bool), 10.0)
    assert feats.shape == (4, 5) and pmfs.shape == (4, 1, 360)
    assert feats[0].tolist() == [1.0, 0.0, 0.0, 1.0, 1.0]  # present, at the row's own angles, every yaw ok
    assert pmfs[0, 0, 40] == pytest.approx(1.0)
    for r in (1, 2, 3):  # one fence, or (part q) no one-fence maps: the analytic PMF and ok mass
        assert feats[r].tolist() == [0.0, FAR_DEG / 90, FAR_DEG / 90, 0.0, a["analytic_ok"][r]]
        assert np.array_equal(pmfs[r, 0], a["analytic"][r])
    assert list(a["composed_maps"]["memo"]) == [(1, 2, 0.0)]  # made once, reused by the next fit
    pool = np.array([True, True, False, True])  # the downstream map outside the pool: nothing composed
    assert composed_block(a, pool, 10.0)[0][0, 0] == 0.0
    assert composed_block(a, np.ones(4, dtype=bool), 10.0, rows=[1, 2, 3])[0][0, 0] == 0.0  # row 0 not asked
    a["kept"][2] = False  # nor when it has no label
    assert composed_block(a, np.ones(4, dtype=bool), 10.0)[0][0, 0] == 0.0
    a["kept"][2] = True
    del a["composed_maps"]["maps"][2]  # nor without its map
    assert composed_block(a, np.ones(4, dtype=bool), 10.0)[0][0, 0] == 0.0


def test_with_composed_appends_a_component_after_the_neighbours_and_its_inputs():
    from feeder.learn.structured_data import with_composed

    a = _composed_arrays()
    b = with_composed(a, np.ones(4, dtype=bool), 10.0)
    assert b["x"].shape == (4, 7) and b["neighbour_pmf"].shape == (4, 1, 360)
    nb = dict(a, neighbour_pmf=np.repeat(a["analytic"][:, None, :], 2, axis=1), neighbour_offset=np.ones((4, 2)))
    c = with_composed(nb, np.ones(4, dtype=bool), 10.0)
    assert c["neighbour_pmf"].shape == (4, 3, 360) and c["neighbour_pmf"][0, 2, 40] == pytest.approx(1.0)
    assert c["neighbour_offset"].tolist() == [[1.0, 1.0, 0.0]] * 4
    d = with_composed(dict(a, neighbour_pmf=nb["neighbour_pmf"]), np.ones(4, dtype=bool), 10.0, -3.0)
    assert d["neighbour_offset"].tolist() == [[0.0, 0.0, -3.0]] * 4  # the composition starts less trusted
    assert "neighbour_offset" not in b
    with pytest.raises(FeederError, match="neighbour_near_deg must be > 0"):
        with_composed(a, np.ones(4, dtype=bool), 0.0)


def test_one_fence_maps_read_the_kept_one_fence_files_only(tmp_path):
    import json

    from feeder.learn.structured_data import one_fence_maps

    (tmp_path / "p").mkdir()
    np.savez(
        tmp_path / "p" / "none_straight30.npz",
        initial_yaw_deg=np.array([0.0, 90.0, 180.0, 270.0]),
        final_yaw_deg=np.array([10.0, 100.0, 190.0, 280.0]),
        status=np.array(["ok"] * 4),
        meta=np.array(json.dumps({})),
        design=np.array("grid"),
    )
    arrays = {
        "part": np.array(["p", "p", "p"]),
        "config_id": np.array(["none_straight30", "curved20_straight30", "curved20_none"]),
        "kept": np.array([True, True, False]),  # the jammed one-fence row is not read
    }
    entry = one_fence_maps(arrays, tmp_path, 1.0)
    assert list(entry["maps"]) == [0] and entry["sigma_bins"] == 1.0 and entry["memo"] == {}
    assert entry["maps"][0].final.tolist() == [10.0, 100.0, 190.0, 280.0]
    arrays["kept"][2] = True
    with pytest.raises(FeederError, match="curved20_none.npz"):
        one_fence_maps(arrays, tmp_path, 1.0)


@pytest.mark.parametrize("bad", [1, "yes", None])
def test_a_bad_composed_setting_is_refused(bad):
    from omegaconf import OmegaConf

    from feeder.learn.structured_protocol import composed_on

    with pytest.raises(FeederError, match="model.composed must be true or false"):
        composed_on(OmegaConf.create({"model": {"composed": bad}}))
    assert composed_on(OmegaConf.create({"model": {}})) is False


def test_the_protocol_runs_the_fits_it_is_asked_for():
    from feeder.config import compose_config
    from feeder.learn.structured_protocol import protocol_jobs

    a = _toy_library()
    jobs, _ = protocol_jobs(a, compose_config("structured", [*TOY_PROTOCOL, "protocol.fits=[main]"]))
    assert [j[1] for j in jobs] == ["main:0", "main:1"]
    jobs, _ = protocol_jobs(a, compose_config("structured", TOY_PROTOCOL))
    assert [j[0] for j in jobs] == ["groupkfold"] * 3 + ["main"] * 2 + ["locked"]
    for bad in ("[]", "[main,oops]"):
        with pytest.raises(FeederError, match="protocol.fits must be a non-empty list of groupkfold, main, locked"):
            protocol_jobs(a, compose_config("structured", [*TOY_PROTOCOL, f"protocol.fits={bad}"]))


def test_a_bad_fits_setting_is_refused_before_any_work(tmp_path):
    from feeder.learn.structured_protocol import main

    with pytest.raises(FeederError, match="protocol.fits must be a non-empty list"):
        main(["--dataset", str(tmp_path / "missing.npz"), "protocol.fits=[oops]"])


def test_the_protocol_reads_the_composed_maps_and_compares_with_them():
    pytest.importorskip("torch")
    from feeder.config import compose_config
    from feeder.learn.prior import grids
    from feeder.learn.structured_protocol import COMPOSED, comparison_table, run_protocol

    cfg = compose_config("structured", [*TOY_PROTOCOL, "protocol.bootstrap.resamples=50", "model.composed=true"])
    a = _toy_library()
    per_part = 4
    cids = np.array(["none_straight30", "straight35_none", "straight45_none", "straight40_straight30"])
    a["config_id"] = cids[np.tile(np.arange(per_part), len(a["part"]) // per_part)]
    maps = {}
    for i, c in enumerate(a["config_id"]):
        if c == "none_straight30":
            maps[i] = grid_map([100.0] * 4)
        elif c.endswith("_none"):
            maps[i] = grid_map(*DOWNSTREAM)
    a["composed_maps"] = {"maps": maps, "sigma_bins": 1.0, "memo": {}}
    a["frame_deg"] = np.zeros(len(a["part"]))
    long, choices = run_protocol(a, cfg, grids(compose_config("train")["prior"]))
    composed = long[long.predictor == COMPOSED]
    assert set(composed.experiment) == {"test", "fences"}  # known parts only
    table = comparison_table(long, {"resamples": 50, "level": 0.95, "seed": 0})
    assert set(table[table.baseline == COMPOSED].experiment) == {"test", "fences"}
    assert choices.composed.all()


def test_signed_steps_say_on_which_side_each_neighbour_lies():
    """model.neighbour_signed: per neighbour (θ1 step, θ2 step) over 90°, by hand; a cross neighbour
    (other fence types) has only its Location 1 step, a missing one none; the network's inputs gain
    exactly these columns, and the distances alone cannot tell the two sides apart."""
    from feeder.config import compose_config
    from feeder.learn.structured_data import neighbour_block, signed_steps
    from feeder.learn.structured_protocol import neighbour_options

    rows = ["straight30_curved40", "straight40_curved40", "straight20_curved40", "straight30_straight45"]
    idx = np.array([[1, 2, 3], [0, -1, 3], [-1, -1, -1], [0, 1, 2]])
    got = signed_steps(rows, rows, idx)
    want = np.array(
        [
            [10 / 90, 0.0, -10 / 90, 0.0, 0.0, 0.0],  # one above, one below (a bracket); the cross: θ1 alike
            [-10 / 90, 0.0, 0.0, 0.0, -10 / 90, 0.0],
            [0.0] * 6,
            [0.0, 0.0, 10 / 90, 0.0, -10 / 90, 0.0],  # other types: no θ2 step
        ]
    )
    np.testing.assert_allclose(got, want, atol=0.0)
    a = {
        "part": np.array(["p"] * 4),
        "config_id": np.array(rows[:3] + ["straight25_curved50"]),
        "kept": np.array([True, True, True, False]),
        "pmf": np.full((4, 8), 1 / 8),
        "cdf": np.cumsum(np.full((4, 8), 1 / 8), axis=1),
        "analytic": np.full((4, 8), 1 / 8),
        "ok": np.ones(4),
        "analytic_ok": np.ones(4),
    }
    pool = np.array([True, True, True, False])
    plain, _ = neighbour_block(a, pool, 2, 10.0)
    both, _ = neighbour_block(a, pool, 2, 10.0, signed=True)
    assert both.shape[1] == plain.shape[1] + 4
    # row 0's neighbours (40 then 20, 10° each way) and the query's (straight25_curved50: 30 and 20)
    np.testing.assert_allclose(both[0, -6:-2], [10 / 90, 0.0, -10 / 90, 0.0])
    np.testing.assert_allclose(both[3, -6:-2], [5 / 90, -10 / 90, -5 / 90, -10 / 90])
    assert plain[0, 1] == plain[0, 7]  # the same distance either side: only the signed steps tell
    assert neighbour_options(compose_config("structured", []))["signed"] is False
    with pytest.raises(FeederError, match="neighbour_signed must be true or false"):
        neighbour_options(compose_config("structured", ["model.neighbour_signed=3"]))
