"""Rotational order of part outlines."""

from __future__ import annotations

import numpy as np
import pytest

from feeder.errors import FeederError
from feeder.parts import symmetry as S


def ngon(n, r=1.0, phase=0.3, centre=(5.0, -2.0)):
    t = phase + 2 * np.pi * np.arange(n) / n
    return np.column_stack([centre[0] + r * np.cos(t), centre[1] + r * np.sin(t)])


SQUARE = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
RECT = np.array([[0, 0], [2, 0], [2, 1], [0, 1]], dtype=float)
TRIANGLE = np.array([[0, 0], [1, 0], [0.5, np.sqrt(3) / 2]])
LSHAPE = np.array([[0, 0], [3, 0], [3, 1], [1, 1], [1, 3], [0, 3]], dtype=float)


@pytest.mark.parametrize(
    "outline, order",
    [
        (SQUARE, 4),
        (SQUARE * 0.02 + 7.0, 4),  # any unit and frame
        (TRIANGLE, 3),
        (RECT, 2),
        (ngon(6), 6),
        (LSHAPE, 1),
        (ngon(64), S.DEFAULT_MAX_ORDER),  # round: capped
        (ngon(8), 8),
        (ngon(16), 8),  # 16-fold, but 360/12 is not a multiple of 22.5°
        (ngon(5)[::-1], 5),  # clockwise
        (np.vstack([SQUARE, SQUARE[:1]]), 4),  # closing duplicate
    ],
)
def test_rotational_order(outline, order):
    assert S.rotational_order(outline) == order


def test_max_order_caps_and_symmetric_star():
    assert S.rotational_order(ngon(64), max_order=6) == 6
    star_t = np.pi / 2 + np.pi * np.arange(10) / 5
    star = np.column_stack(
        [
            np.where(np.arange(10) % 2 == 0, 1.0, 0.4) * np.cos(star_t),
            np.where(np.arange(10) % 2 == 0, 1.0, 0.4) * np.sin(star_t),
        ]
    )
    assert S.rotational_order(star) == 5


def test_small_defect_breaks_symmetry():
    square = np.array([[0, 0], [1, 0], [1, 1], [0.51, 1], [0.5, 0.98], [0.49, 1], [0, 1]], dtype=float)
    assert S.rotational_order(square) == 1  # a 2 % notch in one side
    assert S.rotational_order(square, tolerance=0.05) == 4


def test_check_order():
    S.check_order(SQUARE, 4)
    S.check_order(SQUARE, 2)
    S.check_order(LSHAPE, 1)
    with pytest.raises(FeederError, match="no 4-fold symmetry"):
        S.check_order(RECT, 4)
    with pytest.raises(FeederError, match="no 2-fold symmetry"):
        S.check_order(LSHAPE, 2)
    with pytest.raises(FeederError, match="no 3-fold"):
        S.check_order(SQUARE, 3)


def test_symmetry_error_values():
    assert S.symmetry_error(SQUARE, 4) == pytest.approx(0.0, abs=1e-12)
    assert S.symmetry_error(SQUARE, 1) == 0.0
    assert S.symmetry_error(RECT, 4) > 0.1


@pytest.mark.parametrize(
    "bad",
    [
        np.zeros((2, 2)),
        np.zeros((4, 3)),
        np.array([[0, 0], [1, 1], [1, 0], [0, 1]], dtype=float),  # bow tie
        np.array([[0, 0], [1, 0], [np.nan, 1]]),
    ],
)
def test_bad_outlines_raise(bad):
    with pytest.raises(FeederError):
        S.rotational_order(bad)


def test_bad_settings_raise():
    with pytest.raises(FeederError):
        S.rotational_order(SQUARE, tolerance=0.0)
    with pytest.raises(FeederError):
        S.rotational_order(SQUARE, max_order=0)
    with pytest.raises(FeederError):
        S.check_order(SQUARE, 0)


def test_rotational_order_equals_measuring_every_order_in_full():
    """The cheap vertex bound skips only orders the full measurement rejects too: the same order
    as measuring the symmetry error of every turn."""
    from pathlib import Path

    from shapely.geometry import Polygon

    from feeder.parts.geometry import load_part

    parts = Path(__file__).resolve().parents[1] / "parts"
    outlines = [LSHAPE, RECT, ngon(6), ngon(64), SQUARE * 0.02 + 7.0]
    outlines += [load_part(parts / f"{n}.stl").outline for n in ("crescent-a", "gear8-a", "star5-a", "keyhole-a")]
    for outline in outlines:
        for n in range(2, S.DEFAULT_MAX_ORDER + 1):
            poly = Polygon(outline)
            assert S._vertex_error(poly, n) <= S._error(poly, n) + S._BOUND_SLACK
        for tol in (S.DEFAULT_SYMMETRY_TOLERANCE, 0.05, 1e-6):
            full = next((n for n in range(S.DEFAULT_MAX_ORDER, 1, -1) if S.symmetry_error(outline, n) <= tol), 1)
            assert S.rotational_order(outline, tol) == full


# ------------------------------------------------------------------------------------------
# through-holes count
# ------------------------------------------------------------------------------------------
def _ring(radius, vertices, centre=(0.0, 0.0)):
    a = 2 * np.pi * np.arange(vertices) / vertices
    return np.column_stack([centre[0] + radius * np.cos(a), centre[1] + radius * np.sin(a)])


def test_holes_take_part_in_the_symmetry():
    square = np.array([(0, 0), (4, 0), (4, 4), (0, 4)], float)
    middle = np.array([(1.5, 1.5), (2.5, 1.5), (2.5, 2.5), (1.5, 2.5)])
    assert S.rotational_order(square, holes=[middle]) == 4  # a square hole in the middle keeps 4-fold
    # two holes opposite each other: a half turn maps them onto each other, a quarter turn does not
    small = np.array([(-0.25, -0.25), (0.25, -0.25), (0.25, 0.25), (-0.25, 0.25)])
    assert S.rotational_order(square, holes=[small + (1.5, 2), small + (2.5, 2)]) == 2
    # one hole off the middle: the centroid moves and no turn maps the part onto itself
    assert S.rotational_order(square, holes=[middle + (1, 0)]) == 1
    assert S.symmetry_error(square, 4, holes=[middle + (1, 0)]) > 0.01
    with pytest.raises(FeederError, match="no 4-fold symmetry"):
        S.check_order(square, 4, holes=[middle + (1, 0)])
    # a 32-gon with a centred 16-gon hole: 8-fold, the largest order up to 12 that both have
    assert S.rotational_order(_ring(1.0, 32), holes=[_ring(0.4, 16)]) == 8
    assert S.rotational_order(_ring(1.0, 32), holes=[_ring(0.2, 16, (0.5, 0.0))]) == 1


# ------------------------------------------------------------------------------------------
# mirror axes (feeder.learn.structured_mirror reads a one-fence label at the other location)
# ------------------------------------------------------------------------------------------
def _turn(points, deg):
    a = np.radians(deg)
    return np.asarray(points, float) @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])


def test_a_mirror_axis_is_found_through_the_centroid():
    rect = np.array([(0, 0), (2, 0), (2, 1), (0, 1)], float)
    assert S.mirror_axis(rect) in (0.0, 90.0)
    ell = np.array([(0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2)], float)  # equal legs: the diagonal
    assert S.mirror_axis(ell) == pytest.approx(45.0)
    kite = np.array([(0, 0), (3, 1), (0, 2), (-1, 1)], float)  # symmetric about y = 1 only, far from the origin
    assert S.mirror_axis(kite + 5.0) == pytest.approx(0.0, abs=1e-9)
    for deg in (17.0, 100.0):  # turned by deg, the axis turns with it (mod 180)
        assert S.mirror_axis(_turn(kite, deg)) == pytest.approx((0.0 + deg) % 180.0)
    assert S.mirror_error(kite, 0.0) == pytest.approx(0.0, abs=1e-12)
    assert S.mirror_error(kite, 90.0) > 0.1


def test_a_part_without_a_mirror_axis_has_none():
    assert S.mirror_axis(np.array([(0, 0), (2, 0), (3, 1), (1, 1)], float)) is None  # a parallelogram
    assert S.mirror_axis(np.array([(0, 0), (3, 0), (3, 1), (1, 1), (1, 2), (0, 2)], float)) is None  # unequal legs
    assert S.mirror_axis(np.array([(0, 0), (1, 0), (0.3, 0.8)], float)) is None  # a scalene triangle
    square = np.array([(0, 0), (4, 0), (4, 4), (0, 4)], float)
    hole = np.array([(0.5, 0.5), (1.5, 0.5), (1.5, 1.0), (0.5, 1.0)])  # breaks every axis of the square
    assert S.mirror_axis(square, holes=[hole + (0.3, 2.1)]) is None
    assert S.mirror_axis(square, holes=[hole + (1.0, 0.0)]) == pytest.approx(90.0)  # centred in x: x = 2 stays
    with pytest.raises(FeederError, match="tolerance"):
        S.mirror_axis(square, tolerance=0.0)
