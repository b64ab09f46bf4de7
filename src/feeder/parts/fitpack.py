"""Interpolating parametric B-spline curves: a port of the FITPACK routines behind
``scipy.interpolate.splprep(x, u=u, s=0, k=k)`` and ``splev`` (P. Dierckx, *Curve and surface
fitting with splines*, 1993: ``parcur``/``fppara``, ``fpbspl``, ``fpgivs``, ``fprota``,
``fpback``, ``splev``).

Why a port: step 5 of the DFT features (:mod:`feeder.parts.features`) needs only this one spline,
but importing ``scipy.interpolate`` costs 0.3-0.6 s, more than computing all of a part's
features. The port replays FITPACK's double-precision arithmetic operation by operation, in the
same order (the B-spline values of all points at once, elementwise; the Givens rotations point by
point, as FITPACK does), so its knots, coefficients and curve points are bit-identical to scipy's
(``tests/test_features.py`` checks this against scipy on every library part and on random curves).

Only the interpolation case is ported (``s = 0``, weights 1, parameters given): the knots are the
parameters themselves (odd ``k``) or midpoints of neighbouring parameters (even ``k``), and the
coefficients solve the interpolation conditions by Givens rotations and back substitution.
"""

from __future__ import annotations

import math

import numpy as np

from feeder.errors import FeederError

MAX_DEGREE = 5  # FITPACK's limit


def interval_index(t: np.ndarray, k: int, x: np.ndarray) -> np.ndarray:
    """FITPACK's knot interval of each ``x`` (1-based ``l`` with ``t(l) <= x < t(l+1)``), clamped
    to ``k + 1 .. n - k - 1`` so that points at or beyond the ends use the end intervals."""
    n = len(t)
    return np.clip(np.searchsorted(t, x, side="right"), k + 1, n - k - 1)


def bspline_values(t: np.ndarray, k: int, x: np.ndarray, interval: np.ndarray) -> list[np.ndarray]:
    """The ``k + 1`` non-zero B-splines of degree ``k`` at each ``x`` in its ``interval`` (1-based ``l``)
    (``fpbspl``: the de Boor-Cox recurrence, zero weight where two knots coincide), as ``k + 1``
    arrays shaped like ``x``."""
    x = np.asarray(x, dtype=np.float64)
    h = [np.ones_like(x)] + [np.zeros_like(x) for _ in range(k)]
    for j in range(1, k + 1):
        hh = [v.copy() for v in h[:j]]
        h[0] = np.zeros_like(x)
        for i in range(1, j + 1):
            t_li = t[interval + i - 1]  # t(li), li = l + i (1-based)
            t_lj = t[interval + i - j - 1]  # t(lj), lj = li - j
            same = t_li == t_lj
            with np.errstate(divide="ignore", invalid="ignore"):
                f = hh[i - 1] / (t_li - t_lj)
                h_i = h[i - 1] + f * (t_li - x)
                h_next = f * (x - t_lj)
            h[i - 1] = np.where(same, h[i - 1], h_i)
            h[i] = np.where(same, 0.0, h_next)
    return h


def fit_interpolating(x: np.ndarray, u: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Knots ``t`` (m + k + 1,) and coefficients ``c`` (idim, m) of the degree-``k`` parametric
    spline through the points ``x`` (idim, m) at the strictly increasing parameters ``u`` (m,):
    what ``splprep(x, u=u, k=k, s=0)`` returns as ``t`` and ``c``."""
    x = np.asarray(x, dtype=np.float64)
    u = np.asarray(u, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != u.shape[0] or u.ndim != 1:
        raise FeederError(f"spline: points {x.shape} and parameters {u.shape} do not match")
    idim, m = x.shape
    if not 1 <= k <= MAX_DEGREE:
        raise FeederError(f"spline: degree must be in 1..{MAX_DEGREE}, got {k}")
    if m <= k:
        raise FeederError(f"spline: {m} points are too few for degree {k}")
    if not np.all(np.diff(u) > 0):
        raise FeederError("spline: parameters must be strictly increasing")
    k1 = k + 1
    n = m + k1  # fppara: nmax, the knots of an interpolating spline
    t = np.empty(n)
    t[:k1] = u[0]
    t[n - k1 :] = u[-1]
    interior = m - k1
    if interior > 0:
        start = k // 2 + 1  # fppara: j = k/2 + 2, 1-based
        if k % 2:
            t[k1 : k1 + interior] = u[start : start + interior]
        else:
            t[k1 : k1 + interior] = (u[start : start + interior] + u[start - 1 : start - 1 + interior]) * 0.5
    nk1 = n - k1
    l_of = interval_index(t, k, u)
    h = np.stack(bspline_values(t, k, u, l_of), axis=1)  # (m, k1): h(1..k1) of each point
    # Each band row of the triangularised observation matrix and its right-hand sides, side by
    # side: [a(j, 1..k1), z(j, 1..idim)]; each incoming row likewise: [h(1..k1), xi(1..idim)].
    # A Givens rotation on pivot i turns the incoming entries i+1..k1 and the right-hand sides
    # against the stored ones (fpgivs, then fprota on each pair: FITPACK's arithmetic exactly).
    band = [[0.0] * (k1 + idim) for _ in range(nk1)]
    pairs = [[(s, i + s) for s in range(1, k1 - i)] + [(k1 + d, k1 + d) for d in range(idim)] for i in range(k1)]
    sqrt = math.sqrt
    for v, j in zip(np.hstack([h, x.T]).tolist(), (l_of - k1).tolist(), strict=True):
        for i in range(k1):
            piv = v[i]
            if piv == 0.0:
                continue
            row = band[j + i]
            ww = row[0]
            store = abs(piv)  # fpgivs
            if store >= ww:
                q = ww / piv
                dd = store * sqrt(1.0 + q * q)
            else:
                q = piv / ww
                dd = ww * sqrt(1.0 + q * q)
            cos = ww / dd
            sin = piv / dd
            row[0] = dd
            for s, r in pairs[i]:  # fprota(cos, sin, incoming, stored)
                b = row[s]
                a = v[r]
                row[s] = cos * b + sin * a
                v[r] = cos * a - sin * b
    c = np.array([_back_substitute(band, [row[k1 + d] for row in band], nk1, k1) for d in range(idim)])
    return t, c


def _back_substitute(a: list[list[float]], z: list[float], n: int, k: int) -> list[float]:
    """``fpback``: solve ``a c = z`` for the upper triangular band matrix ``a`` (n x n, bandwidth k)."""
    c = [0.0] * n
    c[n - 1] = z[n - 1] / a[n - 1][0]
    i = n - 2
    for j in range(2, n + 1):
        store = z[i]
        i1 = j - 1 if j <= k - 1 else k - 1
        a_row = a[i]
        for step in range(1, i1 + 1):
            store = store - c[i + step] * a_row[step]
        c[i] = store / a_row[0]
        i -= 1
    return c


def evaluate(t: np.ndarray, c: np.ndarray, k: int, x: np.ndarray) -> np.ndarray:
    """The spline (knots ``t``, coefficients ``c`` (idim, n - k - 1), degree ``k``) at ``x``:
    (idim, len(x)), what ``splev(x, (t, c, k))`` returns (FITPACK ``splev``, extrapolating from
    the end intervals outside ``[t(k+1), t(n-k)]``)."""
    x = np.asarray(x, dtype=np.float64).ravel()
    l_of = interval_index(t, k, x)
    h = bspline_values(t, k, x, l_of)
    first = l_of - (k + 1)  # 0-based index of the first coefficient of each point's interval
    out = []
    for coef in np.atleast_2d(np.asarray(c, dtype=np.float64)):
        sp = np.zeros_like(x)
        for j in range(k + 1):
            sp = sp + coef[first + j] * h[j]
        out.append(sp)
    return np.array(out)
