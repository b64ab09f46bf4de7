"""The analytic + mean-PMF prior (feeder.learn.prior): hand-made PMFs, wrap-around included."""

from __future__ import annotations

import numpy as np
import pytest

from feeder.errors import FeederError
from feeder.learn import prior as P

BINS = 360


def delta(b: int) -> np.ndarray:
    p = np.zeros(BINS)
    p[b % BINS] = 1.0
    return p


def test_widening_a_peak_at_359_spreads_it_evenly_over_0():
    wide = P.widen(delta(359)[None], 2.0)[0]
    assert wide.sum() == pytest.approx(1.0)
    assert wide[0] == pytest.approx(wide[358]) and wide[1] == pytest.approx(wide[357])
    assert wide.argmax() == 359 and wide[0] > wide[2] > 0
    np.testing.assert_array_equal(P.widen(delta(5)[None], 0)[0], delta(5))


def test_blend_is_a_mixture_of_the_two_pmfs():
    analytic = np.stack([delta(10), delta(200)])
    mean = np.full(BINS, 1.0 / BINS)
    out = P.blend(analytic, mean, 0, 0.6)
    assert out.sum(axis=1) == pytest.approx([1.0, 1.0])
    assert out[0, 10] == pytest.approx(0.6 + 0.4 / BINS) and out[0, 11] == pytest.approx(0.4 / BINS)
    np.testing.assert_allclose(P.blend(analytic, mean, 0, 0.0), np.broadcast_to(mean, (2, BINS)))
    np.testing.assert_allclose(P.blend(analytic, mean, 0, 1.0), analytic)


def test_fit_recovers_the_blend_the_labels_were_made_of():
    """Labels made as 0.3 · analytic + 0.7 · (their own mean) are fitted exactly: R² 1."""
    rng = np.random.default_rng(0)
    analytic = np.stack([delta(b) for b in rng.integers(0, BINS, 12)])
    # the labels' mean is the blend's mean PMF: m = 0.3 · mean(analytic) + 0.7 · m, so m = mean(analytic)
    m = analytic.mean(axis=0)
    pmf = 0.3 * analytic + 0.7 * m
    fit = P.fit_blend(pmf, analytic, np.ones(12, bool), [0, 2, 4], np.linspace(0, 1, 11))
    assert (fit.sigma_bins, fit.weight) == (0.0, pytest.approx(0.3)) and fit.score == pytest.approx(1.0)


def test_fit_uses_the_training_rows_only():
    """A held-out row that would pull the fit elsewhere does not: the analytic PMF is exact on
    the training rows (λ = 1) and wrong on the held-out one."""
    analytic = np.stack([delta(10), delta(100), delta(200)])
    pmf = np.stack([delta(10), delta(100), delta(300)])
    train = np.array([True, True, False])
    fit = P.fit_blend(pmf, analytic, train, [0], [0.0, 0.5, 1.0])
    assert fit.weight == 1.0 and fit.score == pytest.approx(1.0)
    # fitted on the held-out row alone, the mean PMF (that row itself) wins instead
    assert P.fit_blend(pmf, analytic, ~train, [0], [0.0, 0.5, 1.0]).weight == 0.0


@pytest.mark.parametrize(
    "args, message",
    [
        ((np.ones((2, BINS)) / BINS, np.ones((3, BINS)) / BINS, np.ones(2, bool), [0], [0.5]), "differ in shape"),
        ((np.ones((2, BINS)) / BINS, np.ones((2, BINS)) / BINS, np.zeros(2, bool), [0], [0.5]), "at least one row"),
        ((np.ones((2, BINS)) / BINS, np.ones((2, BINS)) / BINS, np.ones(2, bool), [], [0.5]), "at least one sigma"),
        ((np.ones((2, BINS)) / BINS, np.ones((2, BINS)) / BINS, np.ones(2, bool), [-1], [0.5]), ">= 0"),
        ((np.ones((2, BINS)) / BINS, np.ones((2, BINS)) / BINS, np.ones(2, bool), [0], [1.5]), r"\[0, 1\]"),
        ((np.ones((2, BINS)), np.ones((2, BINS)) / BINS, np.ones(2, bool), [0], [0.5]), "sum to 1"),
    ],
)
def test_bad_input_is_a_one_line_error(args, message):
    with pytest.raises(FeederError, match=message):
        P.fit_blend(*args)
