"""A one-fence label read at the other location (feeder.learn.structured_mirror, model.mirror_labels)."""

import math

import numpy as np
import pytest

from feeder.errors import FeederError


def _pmf(bins, *masses):
    out = np.zeros(bins)
    for b, m in masses:
        out[b] = m
    return out


@pytest.mark.parametrize(
    "config, other",
    [
        ("straight30_none", "none_straight30"),
        ("none_straight30", "straight30_none"),
        ("curved0_none", "none_curved0"),
        ("none_curved22.5", "curved22.5_none"),
        ("straight30_curved40", None),
    ],
)
def test_the_mirrored_configuration_moves_the_one_fence_to_the_other_location(config, other):
    from feeder.learn.structured_mirror import mirror_config_id

    assert mirror_config_id(config) == other


def test_reflect_pmf_by_hand_with_the_wrap_around():
    """4 bins of 90° (centres 45, 135, 225, 315): mass at 45° goes to c − 45°."""
    from feeder.learn.structured_mirror import reflect_pmf

    p = _pmf(4, (0, 1.0))
    np.testing.assert_allclose(reflect_pmf(p, 0.0), _pmf(4, (3, 1.0)))  # −45 = 315: across 0/360
    np.testing.assert_allclose(reflect_pmf(p, 90.0), _pmf(4, (0, 1.0)))  # 45 is its own image
    np.testing.assert_allclose(reflect_pmf(p, 360.0 + 180.0), _pmf(4, (1, 1.0)))  # 135
    np.testing.assert_allclose(reflect_pmf(p, 45.0), _pmf(4, (3, 0.5), (0, 0.5)))  # 0: between two bins
    q = _pmf(4, (1, 0.25), (2, 0.75))
    np.testing.assert_allclose(reflect_pmf(q, 0.0), _pmf(4, (2, 0.25), (1, 0.75)))
    rng = np.random.default_rng(0)
    r = rng.random((3, 36))
    for c in (0.0, 70.0, 350.0):  # a whole-bin reflection is its own inverse, and keeps the mass
        np.testing.assert_allclose(reflect_pmf(reflect_pmf(r, c), c), r)
        np.testing.assert_allclose(reflect_pmf(r, c + 3.3).sum(axis=1), r.sum(axis=1))


def test_label_mirror_deg_by_hand():
    """A kite symmetric about the x axis (α = 0): c = 180 − 2α + 2 · frame; about 30°: 120 + 2 · frame."""
    from feeder.learn.structured_mirror import label_mirror_deg

    kite = np.array([(-1.0, 0.0), (0.0, -1.0), (3.0, 0.0), (0.0, 1.0)])
    assert label_mirror_deg(kite, [], 0.0) == pytest.approx(180.0)
    assert label_mirror_deg(kite, [], 17.0) == pytest.approx(214.0)
    a = math.radians(30.0)
    turned = kite @ np.array([[math.cos(a), math.sin(a)], [-math.sin(a), math.cos(a)]])
    assert label_mirror_deg(turned, [], 0.0) == pytest.approx(120.0)
    assert label_mirror_deg(turned, [], -100.0) == pytest.approx((120.0 - 200.0) % 360.0)
    parallelogram = np.array([(0, 0), (2, 0), (3, 1), (1, 1)], float)
    assert math.isnan(label_mirror_deg(parallelogram, [], 0.0))
    with pytest.raises(FeederError, match="finite"):
        label_mirror_deg(kite, [], math.nan)


def test_the_relation_holds_for_the_simulated_final_yaws_of_a_mirror_image():
    """The constant's sign and frame: a kite's image x → −x is the kite turned by c (part frame),
    so a final yaw y of the image is the kite at y + c; the bench's rule (image at none | F ends at
    −y where the kite at F | none ends at y) then gives label[F | none](y) = label[none | F](c − y)."""
    from feeder.learn.structured_mirror import label_mirror_deg
    from feeder.parts.symmetry import mirror_axis

    kite = np.array([(-1.0, 0.0), (0.0, -1.0), (3.0, 0.0), (0.0, 1.0)])
    for deg in (0.0, 25.0, 71.0):
        a = math.radians(deg)
        part = kite @ np.array([[math.cos(a), math.sin(a)], [-math.sin(a), math.cos(a)]])
        c = label_mirror_deg(part, [], 0.0)
        image = part * np.array([-1.0, 1.0])
        b = math.radians(c)
        turned = part @ np.array([[math.cos(b), math.sin(b)], [-math.sin(b), math.cos(b)]])
        # the image and the part turned by c are the same point set (up to the vertex order)
        key = lambda p: sorted(map(tuple, np.round(p, 9)))  # noqa: E731
        assert key(turned) == key(image)
        assert mirror_axis(part) == pytest.approx(deg % 180.0)


def _rows():
    """Part p (mirror constant 90°): straight30 at Location 1, a two-fence row and curved40 at
    Location 2; part q (no mirror axis): straight30 at Location 1."""
    bins = 8
    pmf = np.stack([_pmf(bins, (1, 1.0)), _pmf(bins, (2, 1.0)), _pmf(bins, (0, 0.5), (3, 0.5)), _pmf(bins, (5, 1.0))])
    return {
        "part": np.array(["p", "p", "p", "q"]),
        "config_id": np.array(["straight30_none", "straight30_straight45", "none_curved40", "straight30_none"]),
        "kept": np.ones(4, dtype=bool),
        "pmf": pmf,
        "cdf": np.cumsum(pmf, axis=1),
        "analytic": np.roll(pmf, 1, axis=1),
        "ok": np.array([0.9, 0.8, 0.7, 0.6]),
        "analytic_ok": np.ones(4),
        "mirror_deg": np.array([90.0, 90.0, 90.0, math.nan]),
    }


def test_with_mirrors_appends_each_one_fence_label_of_a_symmetric_part_read_at_the_other_location():
    from feeder.learn.structured_mirror import reflect_pmf, with_mirrors

    a = _rows()
    out, pool, src = with_mirrors(a, np.ones(4, dtype=bool))
    np.testing.assert_array_equal(src, [0, 2])  # not the two-fence row, not part q
    assert out["config_id"].tolist()[4:] == ["none_straight30", "curved40_none"]
    assert out["part"].tolist()[4:] == ["p", "p"] and pool.tolist() == [True] * 6
    np.testing.assert_allclose(out["pmf"][4], reflect_pmf(a["pmf"][0], 90.0))
    np.testing.assert_allclose(out["pmf"][4], _pmf(8, (0, 1.0)))  # bin 1 (67.5°) → 90 − 67.5 = 22.5°: bin 0
    np.testing.assert_allclose(out["analytic"][5], reflect_pmf(a["analytic"][2], 90.0))
    np.testing.assert_allclose(out["cdf"][4:], np.cumsum(out["pmf"][4:], axis=1))
    np.testing.assert_allclose(out["ok"][4:], [0.9, 0.7])
    for key in ("pmf", "analytic", "ok", "config_id"):  # the rows themselves unchanged
        np.testing.assert_array_equal(out[key][:4], a[key])
    # only pool rows are mirrored; without mirror constants nothing is
    _, pool, src = with_mirrors(a, np.array([False, True, True, True]))
    np.testing.assert_array_equal(src, [2])
    plain = {k: v for k, v in a.items() if k != "mirror_deg"}
    out, pool, src = with_mirrors(plain, np.ones(4, dtype=bool))
    assert src.size == 0 and len(out["part"]) == 4 and pool.tolist() == [True] * 4
    with pytest.raises(FeederError, match="pool"):
        with_mirrors(a, np.ones(3, dtype=bool))


def test_a_query_at_the_other_location_reads_the_mirrored_label_as_its_neighbour():
    """A none_straight35 query of part p: without mirror constants it has no label of its fence
    types; with them its neighbour is straight30_none read at Location 2, 5° away, reflected, in
    the neighbour inputs and in the gated fallback alike."""
    from feeder.learn.structured_blend import gated_pmfs
    from feeder.learn.structured_data import neighbour_block, neighbour_rows
    from feeder.learn.structured_mirror import reflect_pmf

    a = _rows()
    query = {"part": "p", "config_id": "none_straight35", "kept": True, "ok": 0.5, "analytic_ok": 0.4}
    query |= {"mirror_deg": 90.0, "pmf": np.zeros(8), "cdf": np.zeros(8), "analytic": _pmf(8, (6, 1.0))}
    a = {k: np.concatenate([v, np.asarray([query[k]])]) for k, v in a.items()}
    pool = np.array([True, True, True, True, False])
    idx, dist = neighbour_rows(a, pool, k=1)
    assert idx[4, 0] >= 5 and dist[4, 0] == 5.0  # a mirrored row, 5° away
    # the caller's own neighbour_source is read as it is, and gives the same neighbours
    from feeder.learn.structured_data import neighbour_source

    given = neighbour_rows(a, pool, k=1, source=neighbour_source(a, pool))
    np.testing.assert_array_equal(given[0], idx)
    np.testing.assert_array_equal(given[1], dist)
    src, src_pool = neighbour_source(a, pool)
    none_found = neighbour_rows(a, pool, k=1, source=(src, np.zeros_like(src_pool)))[0]
    assert (none_found == -1).all()  # it is that pool that is searched, not one built again
    feats, pmfs = neighbour_block(a, pool, 1, 10.0)
    want = reflect_pmf(a["pmf"][0], 90.0)
    np.testing.assert_allclose(pmfs[4, 0], want)
    assert feats[4, 0] == 1.0 and feats[4, 5] == pytest.approx(0.9)  # present, the source's ok share
    np.testing.assert_allclose(gated_pmfs(a, pool, [4], 5.0)[0], want)
    np.testing.assert_allclose(gated_pmfs(a, pool, [4], 2.5)[0], a["analytic"][4])
    plain = {k: v for k, v in a.items() if k != "mirror_deg"}
    idx, _ = neighbour_rows(plain, pool, k=1)
    assert idx[4, 0] == -1
    np.testing.assert_allclose(neighbour_block(plain, pool, 1, 10.0)[1][4, 0], a["analytic"][4])
    np.testing.assert_allclose(gated_pmfs(plain, pool, [4], 180.0)[0], a["analytic"][4])


def test_bad_mirror_setting_is_a_one_line_error():
    from feeder.config import compose_config
    from feeder.learn.structured_mirror import mirror_labels

    assert mirror_labels(compose_config("structured", ["model.mirror_labels=true"])) is True
    with pytest.raises(FeederError, match="mirror_labels must be true or false"):
        mirror_labels(compose_config("structured", ["model.mirror_labels=3"]))
