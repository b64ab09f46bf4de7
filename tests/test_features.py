import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import shapely

from feeder.cli import main as cli
from feeder.errors import FeederError
from feeder.parts.features import (
    DFT,
    as_vector,
    dft_features,
    features_of_file,
    frame_deg,
    frequencies,
    outline_samples,
    planar_points,
    principal_align,
    read_xyz,
    reconstruct,
    reconstruction_mse,
)
from feeder.parts.geometry import face_cloud, load_part, stl_bytes

PARTS = Path("parts")
FEEDER = str(Path(sys.executable).with_name("feeder"))


def _rot(deg):
    a = math.radians(deg)
    return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])


def _write_xyz(path, pts2, z=5.0):
    arr = np.column_stack([pts2, np.full(len(pts2), z)])
    path.write_text("".join(f"{float(x)!r} {float(y)!r} {float(zz)!r}\n" for x, y, zz in arr))
    return path


# ---------------------------------------------------------------- pure pieces by hand
def test_dft_selection_by_hand():
    n = np.arange(DFT.samples)
    z = 3 * np.exp(2j * np.pi * 2 * n / 100) + 1 * np.exp(-2j * np.pi * n / 100 + 0.5j)
    f = dft_features(z, 3)
    assert f["k"][:2] == [2, -1]
    np.testing.assert_allclose(f["magnitude"][:2], [300, 100])
    np.testing.assert_allclose(f["phase"][:2], [0.0, 0.5], atol=1e-12)
    assert f["magnitude"][2] < 1e-9
    assert list(frequencies(4)) == [0, 1, -2, -1]
    np.testing.assert_allclose(reconstruct(z, 2), z, atol=1e-12)
    assert as_vector(f).tolist()[:3] == [2, pytest.approx(300), pytest.approx(0.0, abs=1e-12)]


def test_principal_align_is_a_proper_rotation_with_long_axis_first():
    rng = np.random.default_rng(0)
    pts = rng.uniform([-4, -1], [4, 1], size=(500, 2))
    pts = np.vstack([pts, [[3.5, 0.9], [3.9, 0.95]]])  # chiral asymmetry
    moved = pts @ _rot(33).T + [10, -3]
    a = principal_align(moved)
    cov = np.cov(a.T)
    assert cov[0, 0] > cov[1, 1] and abs(cov[0, 1]) < 1e-9
    # a rotation (det +1) maps the original centred points onto the aligned ones
    c = pts - pts.mean(axis=0)
    r, *_ = np.linalg.lstsq(c, a, rcond=None)
    assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-9)
    np.testing.assert_allclose(principal_align(pts @ _rot(-71).T), a, atol=1e-9)


# ---------------------------------------------------------------- invariances
@pytest.mark.parametrize("part", ["lshape-a", "star5-a", "rect-sq", "crescent-a", "gear12-a"])
def test_rotated_translated_copy_gives_same_sorted_magnitudes(part):
    pts = read_xyz(PARTS / f"{part}.xyz")
    base = np.sort(dft_features(outline_samples(planar_points(pts, part)))["magnitude"])
    rng = np.random.default_rng(1)
    for deg in [23.0, 90.0, 161.0, 287.0]:
        moved = pts.copy()
        moved[:, :2] = pts[:, :2] @ _rot(deg).T + [312.5, -87.25]
        moved = moved[rng.permutation(len(moved))] / 1000.0  # shuffled, and in metres
        mags = np.sort(dft_features(outline_samples(planar_points(moved, part)))["magnitude"])
        np.testing.assert_allclose(mags, base, rtol=0.02)


@pytest.mark.parametrize("part", ["lshape-a", "keyhole-a", "tshape-a", "blob-b", "rect-sq", "hex-a", "circle-a"])
def test_resampled_rotated_face_gives_same_magnitudes(part):
    """A face sampled afresh in a rotated pose (a different lattice): within 2 % of |a|max."""
    outline = load_part(PARTS / f"{part}.stl").outline * 1000.0
    base = np.sort(dft_features(outline_samples(face_cloud(outline, 4000)))["magnitude"])
    for deg in [17.0, 133.0]:
        moved = outline @ _rot(deg).T + [250.0, -40.0]
        mags = np.sort(dft_features(outline_samples(face_cloud(moved, 4000)))["magnitude"])
        assert np.max(np.abs(mags - base)) <= 0.02 * base.max()


def test_ellipse_is_reconstructed_by_its_dominant_coefficients():
    a, b = 30.0, 12.0
    t = 2 * np.pi * np.arange(128) / 128
    outline = np.column_stack([a * np.cos(t), b * np.sin(t)]) @ _rot(25).T
    z = outline_samples(face_cloud(outline, 4000))
    f = dft_features(z)
    # centrally symmetric: the dominant harmonics are odd, led by k = +1 and k = -1
    assert set(f["k"][:2]) == {1, -1}
    assert all(k % 2 == 1 for k in f["k"][:6])
    energy = np.abs(np.fft.fft(z)) ** 2
    assert np.sum(np.square(f["magnitude"][:2])) > 0.98 * energy.sum()
    assert np.sum(np.square(f["magnitude"][:6])) > 0.999 * energy.sum()
    rec = reconstruct(z, 15)
    assert reconstruction_mse(z, 15) < 1e-5
    assert reconstruction_mse(z, 4) < reconstruction_mse(z, 2) < reconstruction_mse(z, 1)
    # the reconstruction keeps the ellipse's proportions
    assert np.ptp(rec.real) / np.ptp(rec.imag) == pytest.approx(a / b, rel=0.02)


@pytest.mark.parametrize("shape", ["circle", "square"])
def test_tied_axes_give_finite_identical_output(tmp_path, shape):
    if shape == "circle":
        t = 2 * np.pi * np.arange(64) / 64
        outline = 20 * np.column_stack([np.cos(t), np.sin(t)])
    else:
        outline = np.array([(0, 0), (40, 0), (40, 40), (0, 40)], float)
    path = _write_xyz(tmp_path / f"{shape}.xyz", face_cloud(outline, 3000))
    f1, f2 = features_of_file(path), features_of_file(path)
    assert f1 == f2
    assert np.all(np.isfinite(as_vector(f1)))
    stl = tmp_path / f"{shape}.stl"
    stl.write_bytes(stl_bytes(outline / 1000.0, 0.008))
    assert features_of_file(stl) == features_of_file(stl)


def test_units_and_stl_agree_with_xyz(tmp_path):
    pts = read_xyz(PARTS / "keyhole-a.xyz")
    mm = features_of_file(PARTS / "keyhole-a.xyz")
    metres = features_of_file(_write_xyz(tmp_path / "m.xyz", pts[:, :2] / 1000.0, 0.008))
    np.testing.assert_allclose(metres["magnitude"], mm["magnitude"], rtol=0.01)
    stl = features_of_file(PARTS / "keyhole-a.stl")
    assert np.max(np.abs(np.array(stl["magnitude"]) - mm["magnitude"])) < 0.02 * mm["magnitude"][0]
    outline = load_part(PARTS / "keyhole-a.stl").outline
    (tmp_path / "mm.stl").write_bytes(stl_bytes(outline * 1000.0, 8.0))
    assert features_of_file(tmp_path / "mm.stl")["magnitude"] == pytest.approx(stl["magnitude"], rel=0.01)


def test_constant_axis_other_than_z_is_dropped(tmp_path):
    pts = read_xyz(PARTS / "tshape-a.xyz")
    path = tmp_path / "yz.xyz"
    path.write_text("".join(f"7.5,{x},{y}\n" for x, y, _ in pts))  # commas, constant x
    ref = features_of_file(PARTS / "tshape-a.xyz")
    got = features_of_file(path)
    np.testing.assert_allclose(np.sort(got["magnitude"]), np.sort(ref["magnitude"]), rtol=0.02)


# ---------------------------------------------------------------- CLI and bad input
def test_cli_prints_the_45_values(capsys):
    assert cli(["features", str(PARTS / "star5-a.xyz")]) == 0
    f = json.loads(capsys.readouterr().out)
    assert sorted(f) == ["frame_deg", "k", "magnitude", "phase"]
    assert 0.0 <= f["frame_deg"] < 360.0
    assert len(f["k"]) == len(f["magnitude"]) == len(f["phase"]) == 15
    assert all(isinstance(k, int) and -50 <= k <= 49 for k in f["k"])
    assert f["magnitude"] == sorted(f["magnitude"], reverse=True)
    assert all(-math.pi <= p <= math.pi for p in f["phase"])


def test_cli_out_writes_json(tmp_path, capsys):
    out = tmp_path / "sub" / "f.json"
    assert cli(["features", str(PARTS / "rect-a2.stl"), "--out", str(out)]) == 0
    assert capsys.readouterr().out == ""
    assert json.loads(out.read_text()) == features_of_file(PARTS / "rect-a2.stl")


def _bad_inputs(tmp_path):
    good = stl_bytes(np.array([(0, 0), (0.03, 0), (0.03, 0.02), (0, 0.02)]), 0.005)
    rng = np.random.default_rng(3)
    cases = {
        "empty.xyz": ("", "empty point cloud"),
        "blank.xyz": ("\n\n# only a comment\n", "empty point cloud"),
        "two.xyz": ("0 0 0\n1 0 0\n1 0 0\n0 0 0\n", "fewer than 3 distinct points"),
        "nan.xyz": ("0 0 0\n1 0 0\nnan 1 0\n", "NaN or infinite"),
        "inf.xyz": ("0 0 0\n1 0 0\n0 inf 0\n", "NaN or infinite"),
        "text.xyz": ("0 0 0\nhello world again\n", "not numbers"),
        "cols.xyz": ("0 0\n1 0\n0 1\n", "expected 'x y z'"),
        "line.xyz": ("".join(f"{i} {2 * i} 5\n" for i in range(50)), "collinear"),
        "bumpy.xyz": ("".join(f"{x} {y} {z}\n" for x, y, z in rng.uniform(0, 10, (200, 3))), "not planar"),
        "empty.stl": (b"", "empty STL"),
        "cut.stl": (good[:-7], "truncated"),
        "open.stl": (
            good[: 84 - 4] + (len(good[84:]) // 50 - 1).to_bytes(4, "little") + good[84:-50],
            "not watertight",
        ),
        "shape.obj": ("v 0 0 0\n", "unknown file type"),
    }
    out = {}
    for name, (content, msg) in cases.items():
        path = tmp_path / name
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content)
        out[name] = (path, msg)
    return out


def test_every_bad_input_is_a_one_line_error_without_output(tmp_path, capsys):
    for name, (path, msg) in _bad_inputs(tmp_path).items():
        out = tmp_path / f"{name}.json"
        assert cli(["features", str(path), "--out", str(out)]) == 2, name
        captured = capsys.readouterr()
        err = captured.err.strip()
        assert len(err.splitlines()) == 1, (name, err)
        assert err.startswith("feeder features: error: ") and str(path) in err, err
        assert msg in err, (name, err)
        assert captured.out == ""
        assert not out.exists(), name
        assert not list(tmp_path.glob(f".{out.name}*")), name  # no temp file left


def test_bad_input_via_subprocess(tmp_path):
    cases = _bad_inputs(tmp_path)
    for name in ["nan.xyz", "open.stl"]:
        path, msg = cases[name]
        out = tmp_path / "x.json"
        proc = subprocess.run(
            [FEEDER, "features", str(path), "--out", str(out)], capture_output=True, text=True, timeout=120
        )
        assert proc.returncode == 2
        assert len(proc.stderr.strip().splitlines()) == 1 and msg in proc.stderr
        assert not out.exists()
    proc = subprocess.run([FEEDER, "features", str(PARTS / "blob-a.xyz")], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0
    assert len(json.loads(proc.stdout)["k"]) == 15


def test_planar_points_direct_errors():
    with pytest.raises(FeederError, match="collinear"):
        planar_points(np.array([[0, 0, 1], [1, 1, 1], [2, 2, 1], [3, 3, 1.0]]), "src")


# ---------------------------------------------------------------- the whole library
@pytest.mark.slow
def test_features_work_on_every_library_part():
    xyz = sorted(PARTS.glob("*.xyz"))
    assert len(xyz) >= 48
    vectors = []
    for path in xyz:
        f = features_of_file(path)
        v = as_vector(f)
        assert v.shape == (45,) and np.all(np.isfinite(v))
        assert f["magnitude"] == sorted(f["magnitude"], reverse=True)
        vectors.append(v)
    # different parts give different features, but for a part with holes whose outer contour is
    # another part's (the paper's DFT sees the outer contour only): holed-washer is circle-a's disc
    groups: dict[tuple, list[str]] = {}
    for path, v in zip(xyz, vectors, strict=True):
        groups.setdefault(tuple(np.round(v, 6)), []).append(path.stem)
    shared = [g for g in groups.values() if len(g) > 1]
    assert all(sum(not p.startswith("holed-") for p in g) <= 1 for g in shared), shared
    assert ["circle-a", "holed-washer"] in shared


def test_figure_data_and_s1_table(tmp_path):
    import pandas as pd

    paths = [str(PARTS / f"{p}.xyz") for p in ["rect-a2", "star5-a", "keyhole-a"]]
    data_file = tmp_path / "fig6.npz"
    assert cli(["parts", "fig6-data", *paths, "--out", str(data_file), "--coefficients", "15"]) == 0
    with np.load(data_file) as z:
        assert list(z["name"]) == ["rect-a2", "star5-a", "keyhole-a"] and int(z["coefficients"]) == 15
        assert z["outline"].shape == z["reconstruction"].shape == (3, DFT.samples)
        # normalised units: the larger extent of each aligned outline is the drawable canvas (1),
        # give or take the few pixels the edge dilation and the spline add
        unit = DFT.canvas_px - 1 - 2 * DFT.margin_px
        extent = np.maximum(np.ptp(z["outline"].real, axis=1), np.ptp(z["outline"].imag, axis=1))
        np.testing.assert_allclose(extent, 1.0, atol=5.0 / unit)
        expected = [reconstruction_mse(o * unit, 15) for o in z["outline"]]
        np.testing.assert_allclose(z["mse"], expected)
        np.testing.assert_allclose(z["reconstruction"][0], reconstruct(z["outline"][0], 15))
    fig = tmp_path / "fig6.png"
    assert cli(["figure", "fig6_dft_reconstruction", "--data", str(data_file), "--out", str(fig)]) == 0
    assert fig.stat().st_size > 10_000
    table, s1 = tmp_path / "s1.csv", tmp_path / "s1.png"
    assert cli(["parts", "s1", *paths, "--table", str(table), "--max-coefficients", "50"]) == 0
    frame = pd.read_csv(table)
    assert list(frame["n_coefficients"]) == list(range(1, 51))
    assert (frame["n_parts"] == 3).all()
    # more coefficients never reconstruct worse (top-k by magnitude: Parseval)
    assert np.all(np.diff(frame["mean_mse"]) <= 1e-15)
    assert cli(["figure", "s1_dft_mse", "--data", str(table), "--chosen", "15", "--out", str(s1)]) == 0
    assert s1.stat().st_size > 10_000


def test_figure_data_rejects_a_bad_count(tmp_path):
    out = tmp_path / "fig6.npz"
    assert cli(["parts", "fig6-data", str(PARTS / "rect-a2.xyz"), "--out", str(out), "--coefficients", "0"]) == 2
    assert (
        cli(
            [
                "parts",
                "s1",
                str(PARTS / "rect-a2.xyz"),
                "--table",
                str(tmp_path / "s1.csv"),
                "--max-coefficients",
                "101",
            ]
        )
        == 2
    )
    assert not out.exists() and not (tmp_path / "s1.csv").exists()


# ---------------------------------------------------------------- the feature frame in the part frame
@pytest.mark.parametrize("part", ["lshape-a", "tri-right", "keyhole-a", "rect-a2"])
def test_frame_deg_turns_with_the_part(part, tmp_path):
    """A face turned by ψ in its own file has its feature frame turned by ψ too (mod 360), and the
    aligned points equal the input rotated by -frame_deg (so the labels can follow the features)."""
    pts = read_xyz(PARTS / f"{part}.xyz")[:, :2]
    base = frame_deg(pts)
    c = pts - pts.mean(axis=0)
    np.testing.assert_allclose(principal_align(pts), c @ _rot(-base).T, atol=1e-9)
    for psi in (30.0, 137.0, 250.0):
        turned = frame_deg(pts @ _rot(psi).T)
        assert (turned - base - psi + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=1e-6)
    # through files: the xyz and the STL of the same part agree on the axis; its direction may
    # flip where the skewness along it is sampling noise (a shape symmetric about the second
    # axis). Consistent either way: each file's features and frame come from the same points.
    got = features_of_file(PARTS / f"{part}.xyz")["frame_deg"]
    assert got == pytest.approx(base, abs=1e-9)
    stl = features_of_file(PARTS / f"{part}.stl")["frame_deg"]
    assert (stl - got + 90.0) % 180.0 - 90.0 == pytest.approx(0.0, abs=1.0)


def test_frame_deg_is_none_for_a_face_outside_the_xy_plane(tmp_path):
    pts = read_xyz(PARTS / "tshape-a.xyz")
    path = tmp_path / "yz.xyz"
    path.write_text("".join(f"7.5,{x},{y}\n" for x, y, _ in pts))
    assert features_of_file(path)["frame_deg"] is None
    assert features_of_file(PARTS / "tshape-a.xyz")["frame_deg"] is not None


# ---------------------------------------------------------------- the fast path keeps every value
# as_vector(features) and frame_deg of three library parts, recorded with the code before the
# speed-ups of `feeder bench-predict` (scipy splprep/splev, cKDTree, binary_fill_holes, the face
# lattice measured point by point; the same sha256 as then): tests/data/features_golden.json, written
# by `python tests/test_features.py`. Bit-identical under the recording arithmetic (tests/pins.py);
# elsewhere within FEATURES_RTOL of each value (AVX2 against AVX-512: <= 2.2e-16, one ulp).
FEATURES_GOLDEN = Path(__file__).parent / "data" / "features_golden.json"
FEATURES_RTOL = 1e-9
PINNED_PARTS = ["gear20-a.stl", "keyhole-a.xyz", "rect-a2.stl"]
# library parts whose contours and faces are compared with the straightforward implementations
SAMPLE_PARTS = ["rect-a2", "crescent-a", "gear20-a", "blob-d", "keyhole-a", "tri-sliver", "star5-a", "ushape-deep"]


def _pinned_values(name: str) -> dict:
    import hashlib

    feats = features_of_file(PARTS / name)
    vec = as_vector(feats).astype("<f8")
    sha = hashlib.sha256(vec.tobytes()).hexdigest()
    return {"vector": vec.tolist(), "frame_deg": feats["frame_deg"], "sha256": sha}


@pytest.mark.parametrize("name", PINNED_PARTS)
def test_features_match_the_pin(name):
    """Bit for bit under the arithmetic the pin was recorded with; within 1e-9 relative elsewhere."""
    from pins import assert_pinned

    golden = json.loads(FEATURES_GOLDEN.read_text())
    got, want = _pinned_values(name), golden["parts"][name]
    assert_pinned(got["vector"], want["vector"], golden["recorded_on"], FEATURES_RTOL, 0.0, name)
    assert_pinned(got["frame_deg"], want["frame_deg"], golden["recorded_on"], FEATURES_RTOL, 0.0, name)


def test_features_are_bit_identical_computed_twice_and_in_a_fresh_process():
    """The same computation on the same machine gives the same bits: twice in this process, and
    in a fresh interpreter with another hash seed (nothing depends on set order or state)."""
    name = PINNED_PARTS[0]
    first = _pinned_values(name)
    assert _pinned_values(name) == first
    code = f"import json, test_features as t; print(json.dumps(t._pinned_values({name!r})))"
    env = {**os.environ, "PYTHONHASHSEED": "12345", "PYTHONPATH": str(Path(__file__).parent)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    assert json.loads(out.stdout) == first


def _contour(path):
    from feeder.parts.features import contour_of, load_points, silhouette

    return contour_of(silhouette(principal_align(load_points(path))), str(path))


def test_spline_port_equals_scipy_on_library_contours():
    """feeder.parts.fitpack gives scipy's splprep(s=0)/splev bit for bit (the features' step 5)."""
    from scipy.interpolate import splev, splprep

    from feeder.parts import fitpack
    from feeder.parts.features import spline_samples

    for name in SAMPLE_PARTS:
        contour = _contour(PARTS / f"{name}.stl")
        u = np.linspace(0.0, 1.0, len(contour))
        (t_ref, c_ref, _), _ = splprep([contour[:, 0], contour[:, 1]], u=u, s=0, k=DFT.spline_degree)
        t, c = fitpack.fit_interpolating(contour.T, u, DFT.spline_degree)
        assert t.tobytes() == np.asarray(t_ref).tobytes(), name
        assert c.tobytes() == np.asarray(c_ref)[:, : c.shape[1]].tobytes(), name
        x_ref, y_ref = splev(np.linspace(0.0, 1.0, DFT.samples), (t_ref, c_ref, DFT.spline_degree))
        z_ref = np.asarray(x_ref) + 1j * np.asarray(y_ref)
        assert spline_samples(contour).tobytes() == (z_ref - z_ref.mean()).tobytes(), name


@pytest.mark.parametrize("k", [1, 2, 3, 4, 5])
def test_spline_port_equals_scipy_on_random_curves_of_every_degree(k):
    from scipy.interpolate import splev, splprep

    from feeder.parts import fitpack

    rng = np.random.default_rng(k)
    for m in (k + 1, k + 2, 11, 80):
        u = np.sort(rng.uniform(0.0, 1.0, m))
        x = rng.normal(size=(3, m))
        (t_ref, c_ref, _), _ = splprep(list(x), u=u, s=0, k=k)
        t, c = fitpack.fit_interpolating(x, u, k)
        at = np.linspace(u[0] - 0.1, u[-1] + 0.1, 37)  # beyond the ends too: extrapolation
        assert t.tobytes() == np.asarray(t_ref).tobytes()
        assert fitpack.evaluate(t, c, k, at).tobytes() == np.asarray(splev(at, (t_ref, c_ref, k))).tobytes()
    with pytest.raises(FeederError):
        fitpack.fit_interpolating(np.zeros((2, k)), np.arange(k, dtype=float), k)  # too few points


def test_largest_gap_equals_a_kd_tree():
    from scipy.spatial import cKDTree

    from feeder.parts.features import largest_gap

    rng = np.random.default_rng(0)
    for n, spread in [(2, 480), (3, 480), (40, 480), (500, 100), (4000, 480), (4000, 40), (300, 3)]:
        pts = rng.integers(0, spread, size=(n, 2)) + 10
        uniq = np.unique(pts, axis=0)
        want = float(cKDTree(uniq).query(uniq, k=2)[0][:, 1].max()) if len(uniq) >= 2 else 1.0
        assert largest_gap(pts) == want
    far = np.array([[10, 10], [11, 10], [489, 489], [489, 488], [250, 10]])  # clusters far apart
    assert largest_gap(far) == float(cKDTree(far).query(far, k=2)[0][:, 1].max())
    assert largest_gap(np.array([[5, 5], [5, 5]])) == 1.0  # one distinct pixel


def test_fill_holes_equals_scipy():
    from scipy import ndimage

    from feeder.parts.features import fill_holes

    rng = np.random.default_rng(1)
    for _ in range(50):
        mask = rng.random((int(rng.integers(1, 50)), int(rng.integers(1, 50)))) < rng.uniform(0.2, 0.8)
        assert np.array_equal(fill_holes(mask), ndimage.binary_fill_holes(mask))


def _face_points_reference(outline, spacing):
    """feeder.parts.geometry.face_points as it was: edge by edge, every lattice point measured."""
    outline = np.asarray(outline, dtype=np.float64)
    h = float(spacing)
    nxt = np.roll(outline, -1, axis=0)
    boundary = []
    for p, q in zip(outline, nxt):
        m = max(1, int(np.ceil(np.linalg.norm(q - p) / h)))
        t = np.arange(m)[:, None] / m
        boundary.append(p + t * (q - p))
    lo, hi = outline.min(axis=0), outline.max(axis=0)
    dy = h * np.sqrt(3.0) / 2.0
    ys = lo[1] + dy / 2 + dy * np.arange(int(np.floor((hi[1] - lo[1]) / dy)) + 1)
    xs = lo[0] + h / 4 + h * np.arange(int(np.floor((hi[0] - lo[0]) / h)) + 1)
    gx, gy = np.meshgrid(xs, ys)
    gx = gx + (np.arange(len(ys))[:, None] % 2) * (h / 2)
    grid = np.column_stack([gx.ravel(), gy.ravel()])
    poly = shapely.Polygon(outline)
    grid = grid[shapely.contains_xy(poly, grid[:, 0], grid[:, 1])]
    far = shapely.distance(poly.exterior, shapely.points(grid)) >= h / 2
    return np.concatenate([*boundary, grid[far]])


def _test_outlines():
    from feeder.parts.geometry import clean_outline, read_outline

    rng = np.random.default_rng(2)
    outlines = [clean_outline(read_outline(PARTS / f"{name}.stl")[0]) for name in SAMPLE_PARTS]
    for teeth, scale, offset in [(5, 1e-3, 0.0), (17, 1.0, 300.0), (40, 25.0, -40.0)]:
        angles = np.linspace(0.0, 2 * np.pi, 2 * teeth, endpoint=False)
        radii = np.where(np.arange(2 * teeth) % 2 == 0, 1.0, rng.uniform(0.2, 0.8)) * rng.uniform(0.9, 1.1, 2 * teeth)
        outlines.append(np.column_stack([np.cos(angles), np.sin(angles)]) * radii[:, None] * scale + offset)
    angles = np.linspace(0.0, 2 * np.pi, 1500, endpoint=False)  # a finely tessellated CAD curve
    outlines.append(np.column_stack([np.cos(angles), 0.3 * np.sin(angles)]))
    outlines.append(np.array([[0, 0], [10, 0], [10, 1], [1, 1], [1, 9], [10, 9], [10, 10], [0, 10]], dtype=float))
    return outlines


def test_face_points_equal_the_point_by_point_construction():
    from feeder.parts.geometry import face_points

    for outline in _test_outlines():
        extent = float(np.max(np.ptp(outline, axis=0)))
        for share in (0.3, 0.05, 0.011):
            got = face_points(outline, extent * share)
            assert got.tobytes() == _face_points_reference(outline, extent * share).tobytes()


def test_face_cloud_equals_the_bisection_over_the_reference_points():
    from feeder.parts.geometry import signed_area

    for outline in _test_outlines()[:8]:
        n_points = DFT.stl_cloud_points
        area = abs(signed_area(outline))
        perim = float(np.sum(np.linalg.norm(np.roll(outline, -1, axis=0) - outline, axis=1)))
        a_coef = 2.0 * area / np.sqrt(3.0)
        h = (perim + np.sqrt(perim**2 + 4.0 * a_coef * n_points)) / (2.0 * n_points)
        lo_h, hi_h = h / 2.0, h * 2.0
        want = _face_points_reference(outline, h)
        for _ in range(24):
            if abs(len(want) - n_points) <= max(5, n_points // 200):
                break
            lo_h, hi_h = (h, hi_h) if len(want) > n_points else (lo_h, h)
            h = float(np.sqrt(lo_h * hi_h))
            want = _face_points_reference(outline, h)
        assert face_cloud(outline, n_points).tobytes() == want.tobytes()


def test_features_import_no_scipy():
    """The feature path needs OpenCV and shapely only (scipy.interpolate alone costs 0.3-0.6 s)."""
    code = (
        "import sys\nfrom feeder.parts.features import features_of_file\n"
        f"features_of_file({str(PARTS / 'rect-a2.stl')!r})\n"
        "print(sorted({m.split('.')[0] for m in sys.modules} & {'scipy', 'torch', 'matplotlib'}))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


if __name__ == "__main__":  # re-pin: write tests/data/features_golden.json
    from pins import arithmetic

    golden = {
        "_about": "as_vector(features) (float64) and frame_deg of library parts; sha256 of the vector's "
        "little-endian bytes; recorded_on: the arithmetic of the recording process (tests/pins.py)",
        "recorded_on": arithmetic("numpy", "opencv-python-headless", "shapely"),
        "parts": {name: _pinned_values(name) for name in PINNED_PARTS},
    }
    FEATURES_GOLDEN.write_text(json.dumps(golden, indent=1) + "\n")
