import copy
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from feeder.circular import normalize_yaw
from feeder.cli import main as cli
from feeder.errors import FeederError
from feeder.labels import convergence as C
from feeder.labels import dataset as D
from feeder.labels import grid as G
from feeder.labels import metrics as L
from feeder.lane.fences import parse_config_id

ROOT = Path(__file__).resolve().parents[1]


def small_config(**datasets_overrides):
    cfg = {
        "sim": {"drops": 60, "min_ok_mass": 0.5},
        "fences": {
            "straight_angles": [20, 40, 60],
            "curved_angles": [0, 45, 90],
            "combos": ["straight_none", "curved_none", "none_straight", "straight_curved", "curved_straight"],
            "main_per_part": 5,
            "reserved_combos": ["straight_curved", "curved_straight"],
            "seed": 0,
        },
        "labels": {
            "bins": 360,
            "sigma_bins": 1.0,
            "levels_pct": [10, 50, 100],
            "on_bad": "error",
            "frame": "part",
            "emulated_drops": 200,
        },
        "datasets": {
            "test_fraction": 0.15,
            "split_seed": 42,
            "group_folds": 3,
            "holdout_parts": [],
            "n_holdout": 1,
            "parts_per_part": 4,
            "fences_parts": 2,
            "fences_samples": 3,
            "convergence": {
                "compare_pct": 10,
                "bootstrap": 5,
                "noise_quantile": 0.95,
                "js_threshold": 0.001,
                "fig4_configurations": 4,
                "dkw_alpha": 0.05,
                "peak_prominence": 0.2,
                "seed": 0,
            },
        },
    }
    cfg["datasets"].update(datasets_overrides)
    return cfg


PARTS = ["a", "b", "c", "d", "e", "f"]


def _combo(cid):
    f1, f2 = parse_config_id(cid)
    return f"{f1.type}_{f2.type}"


# ---------------------------------------------------------------- configurations
def test_configurations_structure_and_determinism():
    cfg = small_config()
    df = G.configurations(cfg, PARTS)
    assert list(df.columns) == ["part", "config_id", "loc1", "loc2", "dataset", "split"]
    pd.testing.assert_frame_equal(df, G.configurations(copy.deepcopy(cfg), list(reversed(PARTS))))
    assert not df.duplicated(["part", "config_id"]).any()
    held = G.holdout_parts(cfg, PARTS)
    assert len(held) == 1
    assert set(df.loc[df.dataset == "parts", "part"]) == set(held)
    main = df[df.dataset == "main"]
    assert not set(main.part) & set(held)
    assert (main.groupby("part").size() == 5).all()
    # Parts dataset uses fences seen in Main
    assert set(df.loc[df.dataset == "parts", "config_id"]) <= set(main.config_id)
    assert (df.dataset == "parts").sum() == 4
    # Fences dataset: 3 rows over 2 parts, each part's combo never seen with that part in Main
    fen = df[df.dataset == "fences"]
    assert len(fen) == 3 and fen.part.nunique() == 2
    for part, rows in fen.groupby("part"):
        combos = set(rows.config_id.map(_combo))
        assert len(combos) == 1 and combos <= set(cfg["fences"]["reserved_combos"])
        assert not combos & set(main.loc[main.part == part, "config_id"].map(_combo))
    # splits
    assert set(df.split) == {"train", "test", "fences", "parts"}
    assert (df.loc[df.dataset != "main", "split"] == df.loc[df.dataset != "main", "dataset"]).all()
    n_main = len(main)
    assert (main.split == "test").sum() == int(np.ceil(0.15 * n_main))
    # every angle is on the grid
    for cid in df.config_id:
        for f in parse_config_id(cid):
            if f.type != "none":
                assert f.angle in cfg["fences"][f"{f.type}_angles"]


def test_split_matches_sklearn_train_test_split():
    from sklearn.model_selection import train_test_split

    for n in (7, 40, 1026):
        _, test = train_test_split(np.arange(n), test_size=0.15, random_state=42)
        np.testing.assert_array_equal(np.sort(G.random_test_rows(n, 0.15, 42)), np.sort(test))


def test_adding_a_part_keeps_other_parts_configurations():
    cfg = small_config(fences_parts=0, fences_samples=0, holdout_parts=["a"])
    before = G.configurations(cfg, PARTS)
    after = G.configurations(cfg, PARTS + ["g"])
    key = ["part", "config_id"]
    b = before[before.dataset == "main"][key].sort_values(key).reset_index(drop=True)
    a = after[(after.dataset == "main") & (after.part != "g")][key].sort_values(key).reset_index(drop=True)
    pd.testing.assert_frame_equal(a, b)


def test_wide_parts_leave_the_protocol_rows_unchanged_and_get_their_own_split():
    base = G.configurations(small_config(), PARTS)
    wide = {"parts": ["w-*", "x?"], "per_part": 2}
    df = G.configurations(small_config(wide=wide), PARTS + ["w-1", "w-2", "x9"])
    assert G.wide_parts(small_config(wide=wide), PARTS + ["w-1", "x9", "xx-no"]) == ["w-1", "x9"]
    assert G.protocol_parts(small_config(wide=wide), ["xx-no", "w-1", "b", "x9", "a"]) == ["xx-no", "b", "a"]
    protocol = df[df.dataset != "wide"].reset_index(drop=True)
    pd.testing.assert_frame_equal(protocol, base)
    w = df[df.dataset == "wide"]
    assert (w.split == "wide").all() and sorted(set(w.part)) == ["w-1", "w-2", "x9"]
    assert (w.groupby("part").size() == 2).all()
    assert set(w.config_id.map(_combo)) <= set(small_config()["fences"]["combos"])
    # seeded by the part id: the same rows whatever the other parts
    again = G.configurations(small_config(wide=wide), PARTS + ["w-2"])
    pd.testing.assert_frame_equal(
        again[again.part == "w-2"].reset_index(drop=True), w[w.part == "w-2"].reset_index(drop=True)
    )
    # patterns that match nothing: no wide rows
    none = G.configurations(small_config(wide={"parts": ["zz*"], "per_part": 2}), PARTS)
    pd.testing.assert_frame_equal(none, base)
    with pytest.raises(FeederError, match="per_part"):
        G.configurations(small_config(wide={"parts": ["w-*"], "per_part": 0}), PARTS + ["w-1"])
    with pytest.raises(FeederError, match="no parts left"):
        G.configurations(small_config(wide={"parts": ["*"], "per_part": 1}), PARTS)


def test_holdout_list_and_errors():
    cfg = small_config(holdout_parts=["c", "e"])
    df = G.configurations(cfg, PARTS)
    assert set(df.loc[df.dataset == "parts", "part"]) == {"c", "e"}
    with pytest.raises(FeederError, match="zz"):
        G.configurations(small_config(holdout_parts=["zz"]), PARTS)
    with pytest.raises(FeederError, match="unknown parts or parts of the wider library: w-1"):
        G.configurations(small_config(holdout_parts=["w-1"], wide={"parts": ["w-*"], "per_part": 1}), PARTS + ["w-1"])
    with pytest.raises(FeederError, match="fences_parts"):
        G.configurations(small_config(fences_parts=9), PARTS)


@pytest.mark.parametrize("overlay", ["config/medium.yaml", "config/paper.yaml", "config/paper50.yaml"])
def test_overlays_of_committed_paper_scale_results_keep_the_59_protocol_parts(overlay):
    """The overlays whose results predate the wider library leave it out of the study (parts.exclude),
    so their configurations are those of the paper's 59 parts alone."""
    import yaml
    from snakemake.utils import update_config

    from feeder.parts.library import list_parts

    root = Path(__file__).resolve().parents[1]
    cfg = yaml.safe_load((root / "config/config.yaml").read_text())
    update_config(cfg, yaml.safe_load((root / overlay).read_text()))
    parts = list_parts(root / "parts", cfg["parts"]["include"], cfg["parts"]["exclude"])
    assert len(parts) == 59 and not G.wide_parts(cfg, parts)
    every = list_parts(root / "parts")
    assert len(G.wide_parts(cfg, every)) == 62 and set(every) - set(G.wide_parts(cfg, every)) == set(parts)


@pytest.mark.parametrize("overlay", [None, "config/quick.yaml"], ids=["default", "quick"])
def test_config_matches_table4_scale(overlay):
    """The default (the paper-scale grid) and the cut grid (config/quick.yaml) have the datasets of
    Table 4: holdout parts, Main rows per part, a Fences set over its own parts."""
    from feeder.config import load_study_config

    cfg = load_study_config(*([overlay] if overlay else []), root=ROOT)
    parts = [f"p{i:02d}" for i in range(41)]
    df = G.configurations(cfg, parts)
    sizes = df.groupby("dataset").agg(n=("part", "size"), parts=("part", "nunique"))
    assert sizes.loc["main", "parts"] == 38 and sizes.loc["main", "n"] == 38 * cfg["fences"]["main_per_part"]
    fences = sizes.loc["fences"]
    assert fences.n == cfg["datasets"]["fences_samples"] and fences.parts == cfg["datasets"]["fences_parts"]
    if not overlay:  # the paper's scale (1,048 Main, 78 Fences, 110 Parts rows) drawn ~12 % over what jams
        assert cfg["fences"]["main_per_part"] == 21 and (fences.n, fences.parts) == (90, 18)
        assert sizes.loc["parts", "n"] == 3 * 42
        # the library's 56 Main parts: ~12 % more Main rows than the paper's 1,048 (about 10 % jam)
        assert 1.08 < 56 * cfg["fences"]["main_per_part"] / 1048 < 1.16 and 1.1 < sizes.loc["parts", "n"] / 110 < 1.2
    assert sizes.loc["parts", "parts"] == 3
    # no straight fence at an angle where parts jam (tan(90 - angle) <= 0.5)
    assert max(cfg["fences"]["straight_angles"]) < 63.4


# ---------------------------------------------------------------- feeder vector and scaler
def test_feeder_vector_hand_values():
    v = D.feeder_vector(*parse_config_id("straight30_none"))
    np.testing.assert_array_equal(v, [0, 1, 0, 30, 1, 0, 0, 0])
    v = D.feeder_vector(*parse_config_id("curved0_straight45"))
    np.testing.assert_array_equal(v, [0, 0, 1, 0, 0, 1, 0, 45])


def _feeder_rows(ids):
    return np.stack([D.feeder_vector(*parse_config_id(c)) for c in ids])


def test_scaler_hand_values():
    part = np.zeros((3, 45))
    part[:, 0] = [1.0, 3.0, 100.0]
    part[:, 1] = 7.0  # constant column: SD guarded
    feeder = _feeder_rows(["straight20_none", "straight60_curved10", "straight80_curved90"])
    mask = np.array([True, True, False])
    sc = D.fit_scaler(part, feeder, mask)
    x = sc.transform(part, feeder)
    assert x.shape == (3, 53)
    np.testing.assert_allclose(x[:, 0], [-1.0, 1.0, (100 - 2) / 1.0])
    np.testing.assert_allclose(x[:, 1], 0.0)
    # location-1 angle: min 20, max 60 on training rows; location 2: only 10 seen -> span guarded
    np.testing.assert_allclose(x[:, 45 + 3], [0.0, 1.0, 1.5])
    np.testing.assert_allclose(x[:, 45 + 7], [0.0, 0.0, 80.0])  # none -> 0; 10 -> 0; 90 -> (90-10)/1
    np.testing.assert_array_equal(x[:, 45:48], feeder[:, :3])
    assert D.Scaler.from_dict(json.loads(json.dumps(sc.to_dict()))).transform(part, feeder).tolist() == x.tolist()


def test_scaler_sees_no_statistic_of_held_out_rows():
    rng = np.random.default_rng(0)
    n = 40
    part = rng.normal(size=(n, 45))
    feeder = _feeder_rows(rng.choice(["straight20_curved45", "curved0_straight40", "none_straight60"], size=n))
    split = np.array(["train"] * 25 + ["test"] * 5 + ["fences"] * 5 + ["parts"] * 5)
    mask = split == "train"
    sc = D.fit_scaler(part, feeder, mask)
    # wildly change every non-training row: the scaler must not move
    part2, feeder2 = part.copy(), feeder.copy()
    part2[~mask] = rng.normal(1e6, 1e3, size=part2[~mask].shape)
    feeder2[~mask, 3] = 89.0
    feeder2[~mask, 7] = 1.0
    sc2 = D.fit_scaler(part2, feeder2, mask)
    for k in ("mean", "std", "angle_min", "angle_max"):
        np.testing.assert_array_equal(getattr(sc, k), getattr(sc2, k))
    # and equals statistics computed from the training rows alone
    np.testing.assert_allclose(sc.mean, part[mask].mean(axis=0))
    np.testing.assert_allclose(sc.std, part[mask].std(axis=0))
    sc3 = D.fit_scaler(part[mask], feeder[mask], np.ones(mask.sum(), bool))
    np.testing.assert_allclose(sc.transform(part, feeder), sc3.transform(part, feeder))
    z = sc.transform(part, feeder)[mask, :45]
    np.testing.assert_allclose(z.mean(axis=0), 0, atol=1e-12)
    np.testing.assert_allclose(z.std(axis=0), 1)


# ---------------------------------------------------------------- end to end
def write_sim(path, part, cid, rng, drops=60, ok_frac=0.95, centers=(30.0, 200.0)):
    path.parent.mkdir(parents=True, exist_ok=True)
    status = np.where(rng.random(drops) < ok_frac, "ok", "jammed")
    yaw = np.mod(rng.choice(centers, size=drops) + rng.normal(0, 5, drops), 360)
    yaw[status != "ok"] = np.nan
    np.savez(
        path,
        final_yaw_deg=yaw,
        initial_yaw_deg=rng.uniform(0, 360, drops),
        status=status,
        wall_s=np.float64(1.0),
        meta=np.array(json.dumps({"part": part, "config": cid})),
    )


def make_world(tmp_path, cfg, parts=PARTS):
    df = G.configurations(cfg, parts)
    csv = tmp_path / "configurations.csv"
    df.to_csv(csv, index=False)
    rng = np.random.default_rng(1)
    for p in parts:
        (tmp_path / "features").mkdir(exist_ok=True)
        (tmp_path / "features" / f"{p}.json").write_text(
            json.dumps(
                {
                    "k": rng.integers(-10, 10, 15).tolist(),
                    "magnitude": rng.random(15).tolist(),
                    "phase": rng.uniform(-3, 3, 15).tolist(),
                }
            )
        )
    for r in df.itertuples():
        write_sim(tmp_path / "sim" / r.part / f"{r.config_id}.npz", r.part, r.config_id, rng, drops=cfg["sim"]["drops"])
    return df, csv


def run_build(tmp_path, csv, cfg, out="dataset.npz"):
    settings = json.dumps({k: cfg[k] for k in ("sim", "labels", "datasets")})
    return D.main(
        [
            "build",
            "--configurations",
            str(csv),
            "--features-dir",
            str(tmp_path / "features"),
            "--sim-dir",
            str(tmp_path / "sim"),
            "--settings",
            settings,
            "--out",
            str(tmp_path / out),
        ]
    )


def test_build_end_to_end_and_tables(tmp_path):
    cfg = small_config()
    df, csv = make_world(tmp_path, cfg)
    assert run_build(tmp_path, csv, cfg) == 0
    ds = D.load_dataset(tmp_path / "dataset.npz")
    n = len(df)
    assert ds["pmf"].shape == (n, 360) and ds["pmf_levels"].shape == (n, 3, 360)
    assert ds["part_raw"].shape == (n, 45) and ds["feeder_raw"].shape == (n, 8)
    np.testing.assert_allclose(ds["pmf"].sum(axis=1), 1.0)
    np.testing.assert_allclose(ds["cdf"], np.cumsum(ds["pmf"], axis=1))
    np.testing.assert_allclose(ds["pmf_levels"][:, -1], ds["pmf"])  # 100 % level = full run
    np.testing.assert_array_equal(ds["levels_pct"], [10, 50, 100])
    assert list(ds["split"]) == list(df["split"]) and list(ds["config_id"]) == list(df["config_id"])
    # one fold per part, all parts, >= group_folds distinct folds
    folds = pd.Series(ds["group_fold"]).groupby(ds["part"]).nunique()
    assert (folds == 1).all() and len(folds) == len(PARTS)
    assert set(ds["group_fold"]) == set(range(3))
    # labels equal the label functions applied to the stored file
    i = 4
    with np.load(tmp_path / "sim" / ds["part"][i] / f"{ds['config_id'][i]}.npz") as z:
        y, st = z["final_yaw_deg"], z["status"]
    np.testing.assert_allclose(ds["pmf"][i], L.pmf_from_yaws(y[st == "ok"], 360, 1.0))
    assert ds["n_ok"][i] == (st == "ok").sum()
    assert ds["excluded_part"].size == 0

    tables = tmp_path / "tables"
    assert (
        D.main(
            [
                "table4",
                "--dataset",
                str(tmp_path / "dataset.npz"),
                "--out-csv",
                str(tables / "t4.csv"),
                "--out-md",
                str(tables / "t4.md"),
            ]
        )
        == 0
    )
    t4 = pd.read_csv(tables / "t4.csv")
    assert list(t4.columns[:5]) == ["dataset", "samples", "unique_parts", "purpose", "protocol"]
    assert t4.set_index("dataset").loc["Total (All)", "samples"] == n
    assert t4.set_index("dataset").loc["Parts", "unique_parts"] == 1
    assert "Wide" not in set(t4.dataset)  # no wider library: the paper's rows only

    figdata = tmp_path / "figdata"
    settings = json.dumps({k: cfg[k] for k in ("labels", "datasets")})
    args = [
        "convergence",
        "--dataset",
        str(tmp_path / "dataset.npz"),
        "--settings",
        settings,
        "--dkw-csv",
        str(tables / "dkw.csv"),
        "--js-csv",
        str(tables / "js.csv"),
        "--fig4-data",
        str(figdata / "fig4.csv"),
    ]
    for name in ("fig5", "fig9", "dkw"):
        args += [f"--{name}-data", str(figdata / f"{name}.npz")]
    assert D.main(args) == 0
    fig4 = pd.read_csv(figdata / "fig4.csv")
    assert list(fig4.level_pct) == [10, 50, 100] and list(fig4.n_drops) == [6, 30, 60]
    assert fig4.mean_js.iloc[-1] == pytest.approx(0.0, abs=1e-12) and (fig4.configurations == 4).all()
    with np.load(figdata / "fig5.npz") as z:
        assert z["js"].shape == (n,) and int(z["n_drops_full"]) == 60 and np.isfinite(z["noise_floor"])
    with np.load(figdata / "fig9.npz") as z:
        assert z["pmf"].shape == (z["label"].size, cfg["labels"]["bins"]) and z["yaw_deg"].size == cfg["labels"]["bins"]
        np.testing.assert_allclose(z["pmf"].sum(axis=1), 1.0)
    with np.load(figdata / "dkw.npz") as z:
        assert list(z["n_drops"]) == [6, 30, 60] and z["median_sup"][-1] == 0.0
        assert np.all(z["q10_sup"] <= z["median_sup"]) and np.all(z["median_sup"] <= z["q90_sup"])
    figs = tmp_path / "figs"
    for name, data in (
        ("fig4_js_vs_drops", "fig4.csv"),
        ("fig5_js_hist", "fig5.npz"),
        ("fig9_example_pmfs", "fig9.npz"),
        ("convergence_dkw", "dkw.npz"),
    ):
        assert cli(["figure", name, "--data", str(figdata / data), "--out", str(figs / f"{name}.png")]) == 0
        assert (figs / f"{name}.png").stat().st_size > 1000
    dkw = pd.read_csv(tables / "dkw.csv")
    assert list(dkw.level_pct) == [10, 50, 100]
    assert dkw.loc[dkw.level_pct == 100, "median_sup"].item() == 0.0
    assert ((dkw.fraction_inside_band >= 0) & (dkw.fraction_inside_band <= 1)).all()
    js = pd.read_csv(tables / "js.csv")
    assert js.loc[js.level_pct == 100, "median_js"].item() == pytest.approx(0.0, abs=1e-12)
    assert (js.median_js.diff().dropna() <= 1e-12).all()  # more drops, closer to the full run here


def test_dkw_inside_band_for_exchangeable_drops():
    # i.i.d. drops: the prefix ECDF stays inside the DKW band for about >= 95 % of configurations
    rng = np.random.default_rng(5)
    n, drops = 200, 400
    y = rng.uniform(0, 360, (n, drops))
    levels = np.array([10, 25, 50, 100])
    ds = {
        "part": np.array(["p"] * n),
        "final_yaw_deg": y,
        "n_drops": np.full(n, drops),
        "levels_pct": levels,
        "n_ok_levels": np.tile(drops * levels // 100, (n, 1)),
    }
    table, sup = C.dkw_table(ds, 0.05)
    assert (table.fraction_inside_band >= 0.9).all()
    # a drifting sequence (first half all near 0 deg) falls outside
    y2 = y.copy()
    y2[:, : drops // 2] = rng.uniform(0, 10, (n, drops // 2))
    table2, _ = C.dkw_table({**ds, "final_yaw_deg": y2}, 0.05)
    assert table2.loc[table2.level_pct == 10, "fraction_inside_band"].item() < 0.05


def test_partial_levels_are_compared_with_the_full_run_not_with_the_exact_label():
    """For a sampled map the label is the exact push-forward while the drops are emulated: JS(P_N,
    P_full) must take the 100 % level of those drops (the paper's quantity), which equals the label
    only for drawn designs."""
    full = np.array([[0.5, 0.5, 0, 0, 0, 0, 0, 0]])
    half = np.array([[1.0, 0, 0, 0, 0, 0, 0, 0]])
    exact = np.array([[0.25, 0.75, 0, 0, 0, 0, 0, 0]])
    ds = {"pmf": exact, "pmf_levels": np.stack([half, full], axis=1), "levels_pct": np.array([50, 100])}
    np.testing.assert_array_equal(C.full_run_pmf(ds), full)
    js = C.js_by_level(ds)
    assert js[0, 1] == 0.0  # the full run against itself
    assert js[0, 0] == pytest.approx(L.js_divergence(half[0], full[0]))  # not against the exact label
    assert L.js_divergence(half[0], exact[0]) > js[0, 0]
    no_full = {**ds, "pmf_levels": ds["pmf_levels"][:, :1], "levels_pct": np.array([50])}
    np.testing.assert_array_equal(C.full_run_pmf(no_full), exact)  # no 100 % level: the label


# ---------------------------------------------------------------- bad data
def _break(path, how):
    if how == "missing":
        path.unlink()
    elif how == "truncated":
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 2])
    elif how == "few_ok":
        with np.load(path) as z:
            arrays = {k: z[k] for k in z.files}
        arrays["status"] = np.where(np.arange(arrays["status"].size) < 5, "ok", "fell_off")
        arrays["final_yaw_deg"] = np.where(arrays["status"] == "ok", 10.0, np.nan)
        np.savez(path, **arrays)


@pytest.mark.parametrize("how", ["missing", "truncated", "few_ok"])
def test_bad_sim_file_error_mode_names_file_and_writes_nothing(tmp_path, how):
    cfg = small_config()
    df, csv = make_world(tmp_path, cfg)
    bad = tmp_path / "sim" / df.part[2] / f"{df.config_id[2]}.npz"
    _break(bad, how)
    with pytest.raises(FeederError) as err:
        run_build(tmp_path, csv, cfg)
    assert str(bad) in str(err.value) and "\n" not in str(err.value)
    assert not (tmp_path / "dataset.npz").exists()


@pytest.mark.parametrize("how", ["missing", "truncated", "few_ok"])
def test_bad_sim_file_exclude_mode_counts_it(tmp_path, how, caplog):
    cfg = small_config()
    cfg["labels"]["on_bad"] = "exclude"
    df, csv = make_world(tmp_path, cfg)
    fen = df.index[df.dataset == "fences"][0]
    bad = tmp_path / "sim" / df.part[fen] / f"{df.config_id[fen]}.npz"
    _break(bad, how)
    with caplog.at_level("WARNING"):
        assert run_build(tmp_path, csv, cfg) == 0
    assert str(bad) in caplog.text
    ds = D.load_dataset(tmp_path / "dataset.npz")
    assert len(ds["part"]) == len(df) - 1
    assert list(ds["excluded_config_id"]) == [df.config_id[fen]] and str(bad) in ds["excluded_reason"][0]
    assert np.isfinite(ds["pmf"]).all()
    t4 = D.table4(ds).set_index("dataset")
    assert t4.loc["Fences", "excluded"] == 1 and t4.loc["Total (All)", "excluded"] == 1
    assert t4.loc["Fences", "samples"] == (df.dataset == "fences").sum() - 1


def test_table4_counts_an_excluded_test_row_on_test_and_reports_the_realised_shares(tmp_path):
    """The split is made before exclusion: a bad Test row is a Test exclusion, not a Train one."""
    cfg = small_config()
    cfg["labels"]["on_bad"] = "exclude"
    df, csv = make_world(tmp_path, cfg)
    test_row = df.index[df.split == "test"][0]
    _break(tmp_path / "sim" / df.part[test_row] / f"{df.config_id[test_row]}.npz", "missing")
    assert run_build(tmp_path, csv, cfg) == 0
    ds = D.load_dataset(tmp_path / "dataset.npz")
    assert list(ds["excluded_split"]) == ["test"]
    t4 = D.table4(ds).set_index("dataset")
    assert t4.loc["Main (Test)", "excluded"] == 1 and t4.loc["Main (Train)", "excluded"] == 0
    n_train, n_test = (df.split == "train").sum(), (df.split == "test").sum() - 1
    assert t4.loc["Main (Test)", "share_of_main"] == pytest.approx(n_test / (n_train + n_test))
    assert t4.loc["Main (Train)", "share_of_main"] == pytest.approx(n_train / (n_train + n_test))
    assert np.isnan(t4.loc["Fences", "share_of_main"]) and (t4.excluded_note == "").all()
    old = {k: v for k, v in ds.items() if k != "excluded_split"}  # a dataset from before the key
    assert D.table4(old).loc[0, "excluded"] == 1 and "not recorded" in D.table4(old).loc[0, "excluded_note"]


def test_bad_feature_file_is_an_error(tmp_path):
    cfg = small_config()
    df, csv = make_world(tmp_path, cfg)
    (tmp_path / "features" / f"{df.part[0]}.json").write_text('{"k": [1, 2]}')
    with pytest.raises(FeederError, match=f"{df.part[0]}.json"):
        run_build(tmp_path, csv, cfg)


def test_principal_frame_labels_follow_the_feature_frame(tmp_path):
    cfg = small_config()
    df, csv = make_world(tmp_path, cfg)
    assert run_build(tmp_path, csv, cfg, out="part.npz") == 0
    frames = {p: 37.0 * (i + 1) for i, p in enumerate(PARTS)}  # whole bins: binning shifted yaws = a roll
    for p, deg in frames.items():
        path = tmp_path / "features" / f"{p}.json"
        path.write_text(json.dumps({**json.loads(path.read_text()), "frame_deg": deg}))
    cfg["labels"]["frame"] = "principal"
    assert run_build(tmp_path, csv, cfg, out="principal.npz") == 0
    a, b = D.load_dataset(tmp_path / "part.npz"), D.load_dataset(tmp_path / "principal.npz")
    assert str(a["label_frame"]) == "part" and str(b["label_frame"]) == "principal"
    np.testing.assert_array_equal(a["frame_deg"], 0.0)
    np.testing.assert_array_equal(b["frame_deg"], [frames[p] for p in b["part"]])
    for i in range(len(df)):
        shift = frames[b["part"][i]]
        np.testing.assert_allclose(b["pmf"][i], L.shift_pmf(a["pmf"][i], shift), atol=1e-12)
        np.testing.assert_allclose(b["pmf_levels"][i], L.shift_pmf(a["pmf_levels"][i], shift), atol=1e-12)
        ok = np.isfinite(a["final_yaw_deg"][i])
        np.testing.assert_allclose(b["final_yaw_deg"][i][ok], normalize_yaw(a["final_yaw_deg"][i][ok] + shift))
    np.testing.assert_array_equal(a["part_raw"], b["part_raw"])  # inputs do not change


def test_principal_frame_without_frame_deg_is_an_error_naming_the_file(tmp_path, capsys):
    cfg = small_config()
    _, csv = make_world(tmp_path, cfg)  # feature files without frame_deg
    cfg["labels"]["frame"] = "principal"
    assert (
        cli(
            [
                "datasets",
                "build",
                "--configurations",
                str(csv),
                "--features-dir",
                str(tmp_path / "features"),
                "--sim-dir",
                str(tmp_path / "sim"),
                "--out",
                str(tmp_path / "d.npz"),
                "--settings",
                json.dumps({k: cfg[k] for k in ("sim", "labels", "datasets")}),
            ]
        )
        != 0
    )
    err = capsys.readouterr().err
    assert "frame_deg" in err and ".json" in err and not (tmp_path / "d.npz").exists()
    cfg["labels"]["frame"] = "sideways"
    with pytest.raises(FeederError, match="labels.frame"):
        D.build_dataset(
            pd.read_csv(csv),
            tmp_path / "features",
            tmp_path / "sim",
            {k: cfg[k] for k in ("sim", "labels", "datasets")},
        )


def test_wide_rows_are_counted_in_table4_and_left_out_of_the_convergence_study(tmp_path):
    cfg = small_config(wide={"parts": ["w-*"], "per_part": 2})
    df, csv = make_world(tmp_path, cfg, parts=PARTS + ["w-1", "w-2"])
    assert (df.split == "wide").sum() == 4
    assert run_build(tmp_path, csv, cfg) == 0
    ds = D.load_dataset(tmp_path / "dataset.npz")
    t4 = D.table4(ds).set_index("dataset")
    assert t4.loc["Wide", "samples"] == 4 and t4.loc["Wide", "unique_parts"] == 2
    assert t4.loc["Total (All)", "samples"] == len(df)
    # the same protocol rows without the wide ones: the same convergence study
    df[df.split != "wide"].to_csv(tmp_path / "protocol.csv", index=False)
    assert run_build(tmp_path, tmp_path / "protocol.csv", cfg, out="protocol.npz") == 0
    settings = {k: cfg[k] for k in ("labels", "datasets")}
    with_wide = C.convergence_data(ds, settings)
    without = C.convergence_data(D.load_dataset(tmp_path / "protocol.npz"), settings)
    for key in ("dkw_table", "js_table", "fig4"):
        pd.testing.assert_frame_equal(with_wide[key], without[key])
    np.testing.assert_array_equal(with_wide["fig5"]["js"], without["fig5"]["js"])
