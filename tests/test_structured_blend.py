"""The structured predictor's answer blended with its fallback (feeder.learn.structured_blend)."""

import numpy as np
import pandas as pd
import pytest
from test_structured import TOY_PROTOCOL, _toy_library

from feeder.errors import FeederError


def _pmf(bins, *masses):
    """A PMF of ``bins`` bins with ``masses`` as {bin: mass}."""
    out = np.zeros(bins)
    for b, m in masses:
        out[b] = m
    return out


def test_blended_mixes_the_two_answers_by_the_weight():
    from feeder.learn.structured_blend import blended

    a, b = _pmf(4, (0, 1.0)), _pmf(4, (2, 1.0))
    np.testing.assert_allclose(blended(a[None], b[None], 0.25), [[0.25, 0, 0.75, 0]])
    np.testing.assert_allclose(blended(a[None], b[None], 1.0), a[None])
    # one weight per row (blend.by_fallback)
    two = blended(np.stack([a, a]), np.stack([b, b]), np.array([0.25, 1.0]))
    np.testing.assert_allclose(two, [[0.25, 0, 0.75, 0], [1, 0, 0, 0]])


def test_row_weights_take_each_rows_fallback_kind():
    from feeder.learn.structured_blend import blends_anything, row_weights

    split = {"weight": 0.3, "analytic_weight": 0.8}
    np.testing.assert_allclose(row_weights(split, [True, False, True]), [0.3, 0.8, 0.3])
    np.testing.assert_allclose(row_weights({"weight": 0.4}, [True, False]), [0.4, 0.4])  # a file of before
    assert not blends_anything(None) and not blends_anything({"weight": 1.0})
    assert blends_anything({"weight": 1.0, "analytic_weight": 0.9}) and blends_anything({"weight": 0.5})


@pytest.mark.parametrize("bad", ["1", "yes", "0.5"])
def test_a_bad_by_fallback_is_a_one_line_error(bad):
    from feeder.config import compose_config
    from feeder.learn.structured_blend import by_fallback

    assert by_fallback(compose_config("structured", [])) in (True, False)
    assert by_fallback(compose_config("structured", ["blend.by_fallback=true"])) is True
    with pytest.raises(FeederError, match="blend.by_fallback must be true or false"):
        by_fallback(compose_config("structured", [f"blend.by_fallback={bad}"]))


def test_choose_weight_picks_the_least_circular_w1_and_ties_to_the_network():
    """Hand-computed: 36 bins of 10°; the truth all in bin 0, the network all in bin 0, the fallback
    all in bin 9 (90° away). W1 of weight w is (1 − w)·90°: weight 1 wins. With the truth in bin 9
    the fallback wins. With the truth half in each, weights 0 and 1 both score 45°: the tie goes to
    the larger (the network), and the even blend is the truth itself."""
    from feeder.learn.structured_blend import choose_weight

    net, fb = _pmf(36, (0, 1.0)), _pmf(36, (9, 1.0))
    weights = [0.0, 0.5, 1.0]
    w, scores = choose_weight(np.cumsum(net)[None], net[None], fb[None], weights)
    assert w == 1.0 and scores == pytest.approx({0.0: 90.0, 0.5: 45.0, 1.0: 0.0})
    w, _ = choose_weight(np.cumsum(fb)[None], net[None], fb[None], weights)
    assert w == 0.0
    half = _pmf(36, (0, 0.5), (9, 0.5))
    w, scores = choose_weight(np.cumsum(half)[None], net[None], fb[None], [0.0, 1.0])
    assert w == 1.0 and scores == pytest.approx({0.0: 45.0, 1.0: 45.0})
    w, scores = choose_weight(np.cumsum(half)[None], net[None], fb[None], weights)  # the even blend is the truth
    assert w == 0.5 and scores[0.5] == pytest.approx(0.0)
    # wrap-around: the fallback in bin 35 is 10° from bin 0, not 350°
    near = _pmf(36, (35, 1.0))
    _, scores = choose_weight(np.cumsum(net)[None], net[None], near[None], [0.0])
    assert scores == {}  # one weight: no rows needed, nothing scored
    _, scores = choose_weight(np.cumsum(net)[None], net[None], near[None], [0.0, 1.0])
    assert scores[0.0] == pytest.approx(10.0)
    assert choose_weight(np.zeros((0, 36)), np.zeros((0, 36)), np.zeros((0, 36)), [0.7]) == (0.7, {})
    with pytest.raises(FeederError, match="chosen on validation rows"):
        choose_weight(np.zeros((0, 36)), np.zeros((0, 36)), np.zeros((0, 36)), weights)


@pytest.mark.parametrize("bad", ["[]", "[1.5]", "[-0.1, 1.0]", "[true]", "[a]"])
def test_bad_blend_weights_are_one_line_errors(bad):
    from feeder.config import compose_config
    from feeder.learn.structured_blend import blend_weights

    assert blend_weights(compose_config("structured", [])) == pytest.approx(np.linspace(0, 1, 11).tolist())
    with pytest.raises(FeederError, match="blend.weights must be"):
        blend_weights(compose_config("structured", [f"blend.weights={bad}"]))


def test_the_gated_fallback_takes_the_nearest_label_of_the_same_fence_types_within_the_gate():
    """Row 0 (straight30) has row 1 (straight35, 5° away) and row 2 (straight45) of its part: within
    a 5° gate its fallback is row 1's label, within 2.5° its analytic PMF. Row 3 (another part) and
    row 4 (other fence types) never lend their label; the specialist's fallback is the analytic PMF."""
    from feeder.learn.structured_blend import fallback_choice, gated_choice, gated_pmfs

    bins = 8
    eye = np.eye(bins)
    a = {
        "part": np.array(["p", "p", "p", "q", "p"]),
        "config_id": np.array(
            ["straight30_none", "straight35_none", "straight45_none", "straight30_none", "curved30_none"]
        ),
        "kept": np.ones(5, dtype=bool),
        "pmf": eye[[1, 2, 3, 4, 5]],
        "analytic": eye[[7, 7, 7, 7, 7]],
    }
    pool = np.array([False, True, True, True, True])
    np.testing.assert_array_equal(gated_pmfs(a, pool, [0], 5.0), eye[[2]])
    np.testing.assert_array_equal(gated_pmfs(a, pool, [0], 2.5), eye[[7]])
    only_others = np.array([False, False, False, True, True])
    np.testing.assert_array_equal(gated_pmfs(a, only_others, [0], 180.0), eye[[7]])
    np.testing.assert_array_equal(fallback_choice(a, pool, [0], None)[0], eye[[7]])
    # which kind each row's fallback is (blend.by_fallback): rows 0 and 4 within 5°, rows 0 and 2 within 2.5°
    _, from_label = gated_choice(a, pool, [0, 2], 5.0)  # row 2 (straight45) has no straight row within 5°
    np.testing.assert_array_equal(from_label, [True, False])
    _, from_label = gated_choice(a, pool, [0, 2], 2.5)
    np.testing.assert_array_equal(from_label, [False, False])
    np.testing.assert_array_equal(fallback_choice(a, pool, [0, 1], None)[1], [False, False])
    a["kept"][1] = False  # a jammed neighbour has no label to lend
    np.testing.assert_array_equal(gated_pmfs(a, pool, [0], 15.0), eye[[3]])


def test_the_protocol_blends_on_validation_and_scores_the_network_alone_beside_it():
    """Main fits: the weight is chosen on validation rows (choice table); each seed answers blended;
    ``structured_unblended`` is the network alone (the run with blend.weights [1.0] scores its
    ensemble the same); the baselines do not move; unseen parts are not blended."""
    pytest.importorskip("torch")
    from feeder.config import compose_config
    from feeder.learn.prior import grids
    from feeder.learn.structured_protocol import ENSEMBLE, UNBLENDED, run_protocol

    prior = grids(compose_config("train")["prior"])
    a = _toy_library(n_parts=12)
    off = run_protocol(a, compose_config("structured", [*TOY_PROTOCOL, "blend.weights=[1.0]"]), prior)
    on = run_protocol(a, compose_config("structured", [*TOY_PROTOCOL, "blend.weights=[0.0, 0.5, 1.0]"]), prior)
    rows_off, rows_on = pd.DataFrame(off[0]), pd.DataFrame(on[0])
    main = on[1][on[1].fit.str.startswith("main")]
    assert set(main.blend_weight) <= {0.0, 0.5, 1.0} and main.blend_val_cw1.notna().all()
    assert (main.blend_val_cw1 <= main.blend_network_val_cw1 + 1e-12).all()  # the network is one of the weights
    assert main.specialist_blend_gate_deg.isna().all() and main.blend_gate_deg.notna().all()
    assert on[1][~on[1].fit.str.startswith("main")].blend_weight.isna().all()
    assert not (rows_off.predictor == UNBLENDED).any()  # off: nothing to compare
    assert (rows_on.predictor == UNBLENDED).sum() == (rows_on.predictor == ENSEMBLE).sum() - (
        rows_on.experiment.str.startswith("unseen") & (rows_on.predictor == ENSEMBLE)
    ).sum()  # every Main row, whatever its fit's weight
    key = ["experiment", "repeat", "part", "config_id"]
    net = rows_on[rows_on.predictor == UNBLENDED].sort_values(key).reset_index(drop=True)
    alone = rows_off[(rows_off.predictor == ENSEMBLE) & rows_off.experiment.isin(net.experiment.unique())]
    alone = alone.sort_values(key).reset_index(drop=True)
    mine = alone.set_index(key).index.isin(net.set_index(key).index)
    np.testing.assert_allclose(net.cw1, alone[mine].cw1.to_numpy())
    assert net.experiment.isin(["test", "fences"]).all()
    base = lambda r: r[~r.predictor.str.startswith("structured")].reset_index(drop=True)  # noqa: E731
    pd.testing.assert_frame_equal(base(rows_off), base(rows_on))
    unseen = lambda r: r[r.experiment.str.startswith("unseen")].reset_index(drop=True)  # noqa: E731
    pd.testing.assert_frame_equal(unseen(rows_off), unseen(rows_on))


def test_by_fallback_chooses_one_weight_per_fallback_kind_on_the_same_fits():
    """The same fits (blending never touches training) with blend.by_fallback: each Main fit's two
    weights come from the grid, its validation W1 is no worse than the one weight's (each kind's
    choice is at most the one weight's on its rows), the network alone scores the same, and a
    specialist (fallback: the analytic PMF only) has one weight."""
    pytest.importorskip("torch")
    from feeder.config import compose_config
    from feeder.learn.prior import grids
    from feeder.learn.structured_protocol import UNBLENDED, run_protocol

    prior = grids(compose_config("train")["prior"])
    a = _toy_library(n_parts=12)
    grid = "blend.weights=[0.0, 0.5, 1.0]"
    wide = "neighbour.gates_deg=[400.0]"  # every same-type label within the gate: both kinds among the rows
    one = run_protocol(a, compose_config("structured", [*TOY_PROTOCOL, grid, wide]), prior)
    two = run_protocol(a, compose_config("structured", [*TOY_PROTOCOL, grid, wide, "blend.by_fallback=true"]), prior)
    main_one, main_two = (c[c.fit.str.startswith("main")].reset_index(drop=True) for c in (one[1], two[1]))
    assert (main_one.blend_analytic_weight == main_one.blend_weight).all() and "blend_label_rows" not in main_one
    # every validation row is of one kind; the toy's validation parts have rows of both
    assert (main_two.blend_label_rows + main_two.blend_analytic_rows == main_two.val_rows).all()
    assert (main_two.blend_label_rows > 0).all() and (main_two.blend_analytic_rows > 0).all()
    assert set(main_two.blend_weight) | set(main_two.blend_analytic_weight) <= {0.0, 0.5, 1.0}
    assert (main_two.blend_val_cw1 <= main_one.blend_val_cw1 + 1e-9).all()
    np.testing.assert_allclose(main_two.blend_network_val_cw1, main_one.blend_network_val_cw1)
    sp = main_two.specialist_blend_weight.notna()
    assert (main_two.specialist_blend_weight[sp] == main_two.specialist_blend_analytic_weight[sp]).all()
    r1, r2 = (pd.DataFrame(r[0]) for r in (one, two))
    key = ["experiment", "repeat", "part", "config_id"]
    u1, u2 = (r[r.predictor == UNBLENDED].sort_values(key).reset_index(drop=True) for r in (r1, r2))
    np.testing.assert_allclose(u1.cw1, u2.cw1)


@pytest.mark.parametrize("gate", [15.0, None])
def test_a_blended_shipped_answer_is_the_protocols_blended_prediction(tmp_path, gate):
    """A shipped fit with a blend answers its weight times the seeds' mean plus the rest times the
    fallback: the part's nearest label of the query's fence types within the gate (row 1,
    straight40, has straight30 and straight50 10° away), else the analytic PMF, as the protocol's
    fallback_choice of the row; a file without a blend answers the network alone."""
    pytest.importorskip("torch")
    from test_structured_shipped import BINS, CONFIGS, PARTS_DIR, _small_study

    from feeder import io
    from feeder.learn.structured import predict
    from feeder.learn.structured_blend import fallback_choice
    from feeder.learn.structured_protocol import fit_protocol
    from feeder.learn.structured_shipped import ShippedStructured, shipped_arrays
    from feeder.mechanics.hull import push_geometry
    from feeder.parts.geometry import load_profile

    cfg, a, scene = _small_study(frame_deg=17.0)
    everything = np.ones(10, dtype=bool)
    fitted = fit_protocol(a, everything, cfg, "shipped", known=True)
    plain = ShippedStructured(shipped_arrays(fitted, a, cfg, "principal", BINS, 1.0, scene))
    fitted["blend"] = {"weight": 0.3, "gate_deg": gate, "scores": {0.3: 1.0, 1.0: 2.0}}
    io.write_npz(tmp_path / "s.npz", **shipped_arrays(fitted, a, cfg, "principal", BINS, 1.0, scene))
    shipped = ShippedStructured.load(tmp_path / "s.npz")
    want_meta = {"weight": 0.3, "analytic_weight": 0.3, "gate_deg": gate, "val_cw1": {"0.3": 1.0, "1.0": 2.0}}
    assert shipped.meta["blend"] == want_meta
    geom = push_geometry(*load_profile(PARTS_DIR / "rect-a3.stl", "auto")[:2])
    row, pool = 1, [0, 2, 3, 4]
    args = (geom, "rect-a3", [CONFIGS[row]], [CONFIGS[i] for i in pool], a["pmf"][pool], a["ok"][pool], scene)
    got, alone = shipped.answer(*args), plain.answer(*args)
    net = np.mean([predict(f, fitted["scaled"], [row], fitted["mean_pmf"])[0] for f in fitted["fits"]], axis=0)
    assert alone == pytest.approx(net, abs=2e-5)
    fallback = fallback_choice(a, everything, [row], gate)[0]
    assert got == pytest.approx(0.3 * net + 0.7 * fallback, abs=2e-5)
    want_fallback = a["pmf"][0] if gate is not None else a["analytic"][row]  # straight30 before straight50
    np.testing.assert_allclose(fallback[0], want_fallback)
    assert np.abs(got - alone).sum() > 1e-3  # the blend moved the answer: the comparison is not vacuous
    # blend.by_fallback: the row answers with its own fallback kind's weight (a label within 15°, else
    # the analytic PMF's)
    fitted["blend"] = {"weight": 0.3, "analytic_weight": 0.6, "gate_deg": gate, "scores": {0.3: 1.0, 1.0: 2.0}}
    io.write_npz(tmp_path / "split.npz", **shipped_arrays(fitted, a, cfg, "principal", BINS, 1.0, scene))
    split = ShippedStructured.load(tmp_path / "split.npz")
    assert split.meta["blend"]["analytic_weight"] == 0.6
    w = 0.3 if gate is not None else 0.6
    assert split.answer(*args) == pytest.approx(w * net + (1 - w) * fallback, abs=2e-5)
