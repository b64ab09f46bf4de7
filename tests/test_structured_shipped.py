"""The shipped structured predictor (feeder.learn.structured_shipped): its numpy network is the
torch one, and its answer for a part's configuration is the protocol's prediction of that row."""

from __future__ import annotations

import numpy as np
import pytest
from factories import grid_map

from feeder.errors import FeederError

BINS = 360
PARTS_DIR = __import__("pathlib").Path(__file__).resolve().parents[1] / "parts"


@pytest.mark.parametrize("kind", ["candidates", "variants"])
def test_the_numpy_network_is_the_torch_network(kind):
    torch = pytest.importorskip("torch")
    from feeder.learn.structured import (
        DIFFUSE,
        Batch,
        NetSettings,
        batch_inputs,
        diffuse_components,
        forward_numpy,
        make_nets,
    )
    from feeder.learn.structured_data import candidate_features

    rng = np.random.default_rng(3)
    n, k, v = 5, 4, 3
    masses = rng.dirichlet(np.ones(k), size=(n, v)).transpose(0, 2, 1) * 0.9  # (n, k, v)
    mask = np.ones((n, k), dtype=bool)
    mask[0, 3] = mask[2, 2:] = False
    arrays = {
        "x": rng.normal(size=(n, 6)),
        "pos": rng.uniform(0, 360, size=(n, k)),
        "mask": mask,
        "masses": masses,
        "cf": candidate_features(masses, mask, 0.05),
        "base_mass": masses[:, :, 0],
        "neighbour_offset": rng.normal(size=(n, 2)),
    }
    arrays["pos"][1, 0] = 359.9  # a candidate at the seam
    extra = rng.dirichlet(np.ones(BINS), size=(n, 2))
    diffuse = diffuse_components(rng.dirichlet(np.ones(BINS), size=n), np.full(BINS, 1 / BINS), 8.0, extra)
    s = NetSettings(7, 4.0, 0.5, 1.5, 6.0, kind, "analytic", -1.0)
    torch.manual_seed(0)
    net, _ = make_nets(6, arrays["cf"].shape[2], len(DIFFUSE) + 2, s, n_variants=v)
    net = net.double()
    with torch.no_grad():
        for p in net.parameters():  # away from the zero start, so every weight counts
            p.copy_(torch.randn_like(p))
    b = Batch.of(arrays, np.arange(n), diffuse, s.start)
    with torch.no_grad():
        want = net(*(t.double() if t.dtype == torch.float32 else t for t in b.args())).numpy()
    params = {name: value.numpy() for name, value in net.state_dict().items()}
    got = forward_numpy(params, s, v, batch_inputs(arrays, np.arange(n), diffuse, s.start))
    assert got == pytest.approx(want, abs=1e-8)  # Batch rounds the inputs to float32
    assert got.sum(axis=1) == pytest.approx(np.ones(n))


# a protocol small enough for two parts and a few configurations: three variants, 30 steps
SMALL = [
    "seeds=2",
    "train.max_steps=30",
    "train.patience_steps=10",
    "train.eval_every=5",
    "search=[{kind: candidates, hidden: 4, weight_decay: 0.01}]",
    "protocol.val_part_fraction=0.5",
    "candidates.variants=[{name: base},{name: no_exit, exit_turns: false},{name: mu0.3, mu: 0.3}]",
]
CONFIGS = ["straight30_none", "straight40_none", "straight50_none", "curved30_none", "straight30_straight45"]


def _small_study(frame_deg: float, configs=CONFIGS, overrides=()):
    """Two parts x five configurations with labels made from their analytic PMFs (rolled 7 bins,
    so the network has something to learn), a label frame of ``frame_deg`` for the first part."""
    from feeder.config import compose_config
    from feeder.labels.dataset import label_smooth_deg
    from feeder.learn.structured_data import candidate_settings, compute_candidates, row_inputs
    from feeder.mechanics.candidates import variants_from_config
    from feeder.mechanics.fence import default_scene

    cfg = compose_config("structured", [*SMALL, *overrides])
    parts = ["rect-a3"] * 5 + ["hex-a"] * 5
    cids = list(configs) * 2
    frames = [frame_deg] * 5 + [0.0] * 5
    scene = default_scene()
    variants = variants_from_config(cfg.candidates.variants)
    cand_cfg = candidate_settings(cfg.candidates, BINS, 1.0)
    assert cand_cfg["label_smooth_deg"] == label_smooth_deg(BINS, 1.0)
    cands = compute_candidates(parts, cids, frames, scene, variants, cand_cfg, PARTS_DIR, BINS, "auto")
    a = row_inputs(cands, cids, len(variants), cand_cfg["max_candidates"], cand_cfg["present_mass"])
    pmf = np.roll(a["analytic"], 7, axis=1)
    a.update(
        part=np.array(parts),
        config_id=np.array(cids),
        kept=np.ones(10, dtype=bool),
        frame_deg=np.array(frames),
        ok=np.linspace(0.5, 0.95, 10),
        pmf=pmf,
        cdf=np.cumsum(pmf, axis=1),
        wide_sigma_bins=float(cfg.model.wide_sigma_bins),
    )
    return cfg, a, scene


def test_the_shipped_answer_is_the_protocols_prediction_of_the_row():
    pytest.importorskip("torch")
    from feeder.learn.structured import predict
    from feeder.learn.structured_protocol import fit_protocol
    from feeder.learn.structured_shipped import ShippedStructured, shipped_arrays
    from feeder.mechanics.hull import push_geometry
    from feeder.parts.geometry import load_profile

    cfg, a, scene = _small_study(frame_deg=17.0)
    fitted = fit_protocol(a, np.ones(10, dtype=bool), cfg, "shipped", known=True)
    shipped = ShippedStructured(shipped_arrays(fitted, a, cfg, "principal", BINS, 1.0, scene))
    assert shipped.frame_of("rect-a3") == 17.0 and shipped.frame_of("hex-a") == 0.0
    outline, holes, _ = load_profile(PARTS_DIR / "rect-a3.stl", "auto")
    geom = push_geometry(outline, holes)
    moved = []
    for row in (1, 4):  # one of three same-type neighbours; one with only a cross neighbour
        pool = [i for i in range(5) if i != row]
        got = shipped.answer(
            geom, "rect-a3", [CONFIGS[row]], [CONFIGS[i] for i in pool], a["pmf"][pool], a["ok"][pool], scene
        )
        want = np.mean([predict(f, fitted["scaled"], [row], fitted["mean_pmf"])[0] for f in fitted["fits"]], axis=0)
        assert got == pytest.approx(want, abs=2e-5)  # the protocol's network runs in float32
        moved.append(float(np.max(np.abs(got - a["analytic"][row]))))
    # the network moved an answer off the analytic PMF, so the comparison is not vacuous (with the arc ride the
    # cross-neighbour row's answer moves by 1.0e-3 and the other's by 1.25e-3)
    assert max(moved) > 1e-3, moved
    with pytest.raises(FeederError, match="not trained with part nope"):
        shipped.frame_of("nope")


def test_a_shipped_fences_specialist_answers_the_queries_with_no_label_of_their_own_combination(tmp_path):
    """model.fences_specialist: the file carries both networks; a query with a label of its own
    type combination gets the default network's prediction of the row, one with only a cross
    neighbour the specialist's (each as the protocol predicts it), through a written file too."""
    pytest.importorskip("torch")
    from feeder import io
    from feeder.learn.structured import predict
    from feeder.learn.structured_protocol import fit_protocol, specialist_cfg
    from feeder.learn.structured_shipped import ShippedStructured, shipped_arrays
    from feeder.mechanics.hull import push_geometry
    from feeder.parts.geometry import load_profile

    cfg, a, scene = _small_study(frame_deg=17.0, overrides=["model.fences_specialist=true"])
    everything = np.ones(10, dtype=bool)
    fitted = fit_protocol(a, everything, cfg, "shipped", known=True)
    spec = fit_protocol(a, everything, specialist_cfg(cfg), "shipped:specialist", known=True)
    io.write_npz(tmp_path / "s.npz", **shipped_arrays(fitted, a, cfg, "principal", BINS, 1.0, scene, specialist=spec))
    shipped = ShippedStructured.load(tmp_path / "s.npz")
    assert set(shipped.networks) == {"default", "specialist"}
    outline, holes, _ = load_profile(PARTS_DIR / "rect-a3.stl", "auto")
    geom = push_geometry(outline, holes)
    answers = {}
    for row, f in ((1, fitted), (4, spec)):  # three same-type neighbours; only a cross neighbour
        pool = [i for i in range(5) if i != row]
        got = shipped.answer(
            geom, "rect-a3", [CONFIGS[row]], [CONFIGS[i] for i in pool], a["pmf"][pool], a["ok"][pool], scene
        )
        want = np.mean([predict(s, f["scaled"], [row], f["mean_pmf"])[0] for s in f["fits"]], axis=0)
        assert got == pytest.approx(want, abs=2e-5)  # the protocol's networks run in float32
        answers[row] = got
    pool = [0, 2, 3]
    ask = lambda rows: shipped.answer(  # noqa: E731
        geom, "rect-a3", [CONFIGS[r] for r in rows], [CONFIGS[i] for i in pool], a["pmf"][pool], a["ok"][pool], scene
    )
    without = ShippedStructured(shipped_arrays(fitted, a, cfg, "principal", BINS, 1.0, scene))
    other = without.answer(
        geom, "rect-a3", [CONFIGS[4]], [CONFIGS[i] for i in (0, 1, 2, 3)], a["pmf"][:4], a["ok"][:4], scene
    )
    # the toy networks stay near their common start, so the specialist's answer is told from the
    # default's by distance: the protocol's specialist lies far nearer than the default network
    want = np.mean([predict(s, spec["scaled"], [4], spec["mean_pmf"])[0] for s in spec["fits"]], axis=0)
    assert np.abs(answers[4] - want).sum() < 0.1 * np.abs(answers[4] - other).sum()
    np.testing.assert_allclose(ask([1, 4]), np.concatenate([ask([1]), ask([4])]), atol=1e-12)  # routed row by row


def test_the_shipped_answer_composes_the_one_fence_maps_as_the_protocol_does():
    pytest.importorskip("torch")
    from feeder.learn.structured import predict
    from feeder.learn.structured_protocol import fit_protocol
    from feeder.learn.structured_shipped import ShippedStructured, shipped_arrays
    from feeder.mechanics.hull import push_geometry
    from feeder.parts.geometry import load_profile

    configs = ["straight30_none", "none_straight45", "straight50_none", "none_curved30", "straight30_straight45"]
    cfg, a, scene = _small_study(17.0, configs, ["model.composed=true"])
    maps = {0: grid_map([40.0, 40.0, 220.0, 220.0]), 1: grid_map([100.0] * 4)}  # downstream, upstream alone
    a["composed_maps"] = {"maps": {**maps, **{i + 5: m for i, m in maps.items()}}, "sigma_bins": 1.0, "memo": {}}
    fitted = fit_protocol(a, np.ones(10, dtype=bool), cfg, "shipped", known=True)
    assert fitted["choice"]["composed"]
    shipped = ShippedStructured(shipped_arrays(fitted, a, cfg, "principal", BINS, 1.0, scene))
    assert shipped.meta["composed"] and shipped.has_neighbour("straight20_straight40", configs[:2])
    assert not shipped.has_neighbour("curved20_straight40", configs[:2])  # no curved downstream fence alone
    outline, holes, _ = load_profile(PARTS_DIR / "rect-a3.stl", "auto")
    geom = push_geometry(outline, holes)
    pool = [0, 1, 2, 3]
    args = (geom, "rect-a3", [configs[4]], [configs[i] for i in pool], a["pmf"][pool], a["ok"][pool], scene)
    got = shipped.answer(*args, pool_maps=maps)
    want = np.mean([predict(f, fitted["scaled"], [4], fitted["mean_pmf"])[0] for f in fitted["fits"]], axis=0)
    assert got == pytest.approx(want, abs=2e-5)
    assert fitted["scaled"]["neighbour_pmf"][4, -1, 57] > 0.3  # composed: 40 deg, turned by the frame's 17
    assert not np.allclose(shipped.answer(*args), got, atol=1e-4)  # without the maps, another answer


def test_a_neighbour_is_of_the_same_fence_types_or_of_the_same_downstream_fence_type():
    from feeder.learn.structured_shipped import ShippedStructured

    shipped = ShippedStructured.__new__(ShippedStructured)
    shipped.meta = {"neighbours": 2, "cross_neighbours": 1}
    pool = ["straight30_none", "curved40_straight20"]
    assert shipped.has_neighbour("straight55_none", pool)  # same types
    assert shipped.has_neighbour("straight20_curved30", pool)  # same downstream fence type, other combination
    assert shipped.has_neighbour("curved60_straight45", pool)
    assert shipped.has_neighbour("curved20_none", pool)  # the curved one, after a straight upstream
    assert not shipped.has_neighbour("curved20_none", pool[:1])  # no curved downstream fence at all
    assert not shipped.has_neighbour("none_straight30", pool)  # no downstream fence: no cross neighbour
    shipped.meta = {"neighbours": 2, "cross_neighbours": 0}
    assert not shipped.has_neighbour("straight20_curved30", pool)


def test_a_file_of_another_format_is_refused():
    from feeder.learn.structured_shipped import ShippedStructured

    with pytest.raises(FeederError, match="format 99"):
        ShippedStructured({"meta": np.array('{"format": 99}')})


def test_fit_structured_refuses_bad_input_in_one_line_and_writes_nothing(tmp_path):
    import os
    import subprocess
    import sys

    def cli(*args):
        proc = subprocess.run([sys.executable, "-m", "feeder", "fit-structured", *args], capture_output=True, text=True)
        return proc.returncode, proc.stderr.strip()

    out = tmp_path / "structured.npz"
    base = ["--sim-dir", str(tmp_path), "--parts-dir", str(PARTS_DIR), "--features-dir", str(tmp_path)]
    for args, message in [
        (["--dataset", str(tmp_path / "none.npz"), "--out", str(out)], "none.npz is missing"),
        (["--dataset", str(tmp_path / "none.npz"), "--out", str(tmp_path / "model.pt")], "ends in .npz"),
        (["--dataset", str(tmp_path / "none.npz"), "--out", str(out), "seeds=oops"], "seeds must be an integer >= 1"),
    ]:
        code, err = cli(*base, *args)
        assert code != 0 and message in err and "\n" not in err and "Traceback" not in err, err
        assert os.listdir(tmp_path) == []


def test_fit_structured_ships_whole_label_neighbours_only():
    from feeder.config import compose_config
    from feeder.learn.structured_shipped import fit_shipped

    for option in ("neighbour_basins", "neighbour_candidates"):
        cfg = compose_config("structured", [f"model.{option}=3"])
        with pytest.raises(FeederError, match="neighbour_basins and neighbour_candidates: 0"):
            fit_shipped({"part": np.array(["a"])}, cfg, {})
    with pytest.raises(FeederError, match="model.cross_only: false"):
        fit_shipped({"part": np.array(["a"])}, compose_config("structured", ["model.cross_only=true"]), {})


def test_the_candidates_key_names_a_missing_part_file(tmp_path):
    from feeder.learn.structured_data import candidates_key

    with pytest.raises(FeederError, match="nope.stl is missing"):
        candidates_key(["nope"], ["straight30_none"], [0.0], {}, [], {}, tmp_path)


def test_a_calibrated_shipped_answer_is_the_protocols_calibrated_prediction(tmp_path):
    """calibration.network: the file keeps each part's mode, chosen on all its labels, and an answer
    computes that mode's PMF of the query as the network's own analytic component: the protocol's
    prediction of the row with its calibrated arrays. rect-a3's labels are one mode's PMFs (rolled
    as the others), so that mode wins however its rows are left out; hex-a's keep the base."""
    pytest.importorskip("torch")
    from feeder import io
    from feeder.learn.structured import predict
    from feeder.learn.structured_calibration import base_and_mode_w1, calibration_settings, compute_mode_pmfs
    from feeder.learn.structured_protocol import fit_protocol
    from feeder.learn.structured_shipped import ShippedStructured, calibrated_arrays, shipped_arrays
    from feeder.mechanics.hull import push_geometry
    from feeder.parts.geometry import load_profile

    modes_cfg = "calibration.modes=[{name: mu0.6, mu: 0.6},{name: no_exit, exit_turns: false}]"
    cfg, a, scene = _small_study(frame_deg=17.0, overrides=[modes_cfg, "calibration.network=true"])
    modes, _ = calibration_settings(cfg)
    smooth = 1.0  # the labels' smoothing (_small_study's sigma of 1 bin)
    a["mode_pmfs"] = compute_mode_pmfs(
        a["part"], a["config_id"], a["frame_deg"], scene, modes, smooth, PARTS_DIR, BINS, "auto"
    )
    a["pmf"][:5] = np.roll(a["mode_pmfs"][:5, 1], 7, axis=1)
    a["cdf"] = np.cumsum(a["pmf"], axis=1)
    a["mode_w1"] = base_and_mode_w1(a["cdf"], a["analytic"], a["mode_pmfs"], a["kept"])
    everything = np.ones(10, dtype=bool)
    c = calibrated_arrays(a, everything, cfg)
    assert (c["calibration_mode"][:5] == 2).all()  # no_exit for rect-a3, on every leave-one-out
    fitted = fit_protocol(c, everything, cfg, "shipped", known=True)
    io.write_npz(tmp_path / "s.npz", **shipped_arrays(fitted, c, cfg, "principal", BINS, 1.0, scene))
    shipped = ShippedStructured.load(tmp_path / "s.npz")
    assert shipped.meta["calibration"]["part_modes"]["rect-a3"] == "no_exit"
    assert shipped.part_mode("rect-a3") == modes[1] and shipped.part_mode("nope") is None
    geom = push_geometry(*load_profile(PARTS_DIR / "rect-a3.stl", "auto")[:2])
    for row in (1, 4):
        pool = [i for i in range(5) if i != row]
        got = shipped.answer(
            geom, "rect-a3", [CONFIGS[row]], [CONFIGS[i] for i in pool], a["pmf"][pool], a["ok"][pool], scene
        )
        want = np.mean([predict(f, fitted["scaled"], [row], fitted["mean_pmf"])[0] for f in fitted["fits"]], axis=0)
        assert got == pytest.approx(want, abs=2e-5)
    # the same fit shipped without the calibration answers otherwise: the comparison is not vacuous
    plain = ShippedStructured(shipped_arrays(fitted, a, cfg, "principal", BINS, 1.0, scene))
    assert plain.part_mode("rect-a3") is None
    pool = [0, 2, 3, 4]
    other = plain.answer(
        geom, "rect-a3", [CONFIGS[1]], [CONFIGS[i] for i in pool], a["pmf"][pool], a["ok"][pool], scene
    )
    mine = shipped.answer(
        geom, "rect-a3", [CONFIGS[1]], [CONFIGS[i] for i in pool], a["pmf"][pool], a["ok"][pool], scene
    )
    assert np.abs(other - mine).sum() > 1e-2
    # on without the modes' PMFs: a one-line error
    with pytest.raises(FeederError, match="modes' PMFs"):
        calibrated_arrays(_small_study(17.0, overrides=["calibration.network=true"])[1], everything, cfg)


def test_a_mirror_shipped_answer_is_the_protocols_prediction_and_reads_the_other_location(tmp_path):
    """model.mirror_labels: the file keeps each part's mirror constant, and the answer for a
    Location 2 query (none_straight35) whose part has labels only at Location 1 (straight30,
    straight40) is the protocol's prediction of the row, which reads those labels reflected; the
    study's description names the label read at the other location."""
    pytest.importorskip("torch")
    from feeder import io
    from feeder.learn.structured import predict
    from feeder.learn.structured_data import row_mirror_degs
    from feeder.learn.structured_protocol import fit_protocol
    from feeder.learn.structured_shipped import ShippedStructured, shipped_arrays
    from feeder.mechanics.hull import push_geometry
    from feeder.parts.geometry import load_profile

    configs = ["straight30_none", "straight40_none", "none_straight35", "curved30_none", "straight30_straight45"]
    cfg, a, scene = _small_study(frame_deg=17.0, configs=configs, overrides=["model.mirror_labels=true"])
    data = {"part": a["part"], "frame_deg": a["frame_deg"], "label_frame": "principal", "settings": "{}"}
    a["mirror_deg"] = row_mirror_degs(data, a["part"], PARTS_DIR, tmp_path)
    assert np.isfinite(a["mirror_deg"]).all()  # a rectangle and a hexagon
    fitted = fit_protocol(a, np.ones(10, dtype=bool), cfg, "shipped", known=True)
    io.write_npz(tmp_path / "s.npz", **shipped_arrays(fitted, a, cfg, "principal", BINS, 1.0, scene))
    shipped = ShippedStructured.load(tmp_path / "s.npz")
    assert shipped.mirror_deg("rect-a3") == pytest.approx(a["mirror_deg"][0])
    assert shipped.mirrored_ids("rect-a3", configs[:2]) == [("none_straight30", 0), ("none_straight40", 1)]
    geom = push_geometry(*load_profile(PARTS_DIR / "rect-a3.stl", "auto")[:2])
    row, pool = 2, [0, 1, 3, 4]
    got = shipped.answer(
        geom, "rect-a3", [configs[row]], [configs[i] for i in pool], a["pmf"][pool], a["ok"][pool], scene
    )
    want = np.mean([predict(f, fitted["scaled"], [row], fitted["mean_pmf"])[0] for f in fitted["fits"]], axis=0)
    assert got == pytest.approx(want, abs=2e-5)
    # the inputs read the mirrored labels: without the constants the same network answers otherwise
    plain = ShippedStructured(
        {**shipped_arrays(fitted, a, cfg, "principal", BINS, 1.0, scene), "meta": _without_mirror(shipped.meta)}
    )
    other = plain.answer(
        geom, "rect-a3", [configs[row]], [configs[i] for i in pool], a["pmf"][pool], a["ok"][pool], scene
    )
    assert np.abs(other - got).max() > 1e-4


def _without_mirror(meta: dict):
    import json

    return np.array(json.dumps({k: v for k, v in meta.items() if k != "mirror_labels"}, sort_keys=True))


def test_a_signed_shipped_answer_is_the_protocols_prediction(tmp_path):
    """model.neighbour_signed: the file says so, and its answer is the protocol's prediction of
    the row, which reads the neighbours' signed angle steps; a file without the key answers as a
    network without those inputs would not."""
    pytest.importorskip("torch")
    import json

    from feeder import io
    from feeder.learn.structured import predict
    from feeder.learn.structured_protocol import fit_protocol
    from feeder.learn.structured_shipped import ShippedStructured, shipped_arrays
    from feeder.mechanics.hull import push_geometry
    from feeder.parts.geometry import load_profile

    cfg, a, scene = _small_study(frame_deg=17.0, overrides=["model.neighbour_signed=true"])
    fitted = fit_protocol(a, np.ones(10, dtype=bool), cfg, "shipped", known=True)
    io.write_npz(tmp_path / "s.npz", **shipped_arrays(fitted, a, cfg, "principal", BINS, 1.0, scene))
    shipped = ShippedStructured.load(tmp_path / "s.npz")
    assert shipped.meta["neighbour_signed"] is True
    geom = push_geometry(*load_profile(PARTS_DIR / "rect-a3.stl", "auto")[:2])
    ids = [str(c) for c in a["config_id"][:5]]
    row, pool = 1, [0, 2, 3, 4]
    got = shipped.answer(geom, "rect-a3", [ids[row]], [ids[i] for i in pool], a["pmf"][pool], a["ok"][pool], scene)
    want = np.mean([predict(f, fitted["scaled"], [row], fitted["mean_pmf"])[0] for f in fitted["fits"]], axis=0)
    assert got == pytest.approx(want, abs=2e-5)
    meta = {k: v for k, v in shipped.meta.items() if k != "neighbour_signed"}
    plain = ShippedStructured(
        {**shipped_arrays(fitted, a, cfg, "principal", BINS, 1.0, scene), "meta": np.array(json.dumps(meta))}
    )
    with pytest.raises(FeederError, match="takes 66 inputs and its file's settings build 60"):
        plain.answer(geom, "rect-a3", [ids[row]], [ids[i] for i in pool], a["pmf"][pool], a["ok"][pool], scene)
