"""The push function: which hull edge a fence turns a part onto, from which contact normals.

Push function (:func:`push_function`)
    Orientation is parametrised by ``φ``, the direction in the part frame of the contact normal
    pointing from the part at the fence. Frictionless (``mu = 0``, Goldberg): the part turns to
    decrease ``r``; the stable orientations are the local minima of ``r``, the normals of hull
    edges whose foot from the centroid falls strictly inside the edge, and each basin extends to
    the neighbouring local maxima (the vertex directions). With fence friction ``mu`` and the
    part sliding along the fence (which it does outside the friction cone, see *jams*), Mason's
    voting theorem gives the turning sense from the friction-cone edge that opposes the slide:
    the contact force ``F = n − mu t`` (``n`` the fence's normal into the part, ``t`` the fence
    direction downstream) makes the moment ``∝ s − mu d`` about the centroid, ``s`` the contact's
    offset downstream from the centroid's foot and ``d`` its distance from the fence. Hence an edge
    is stable iff the foot shifted ``mu · d`` downstream lies strictly inside it, and every basin
    boundary is the vertex direction turned by ``−side · atan(mu)`` (``side`` +1 for a fence on
    the right of the travel direction, −1 on the left). ``mu = 0`` is exactly Goldberg's function;
    the measures of basins do not change with ``mu`` as long as the set of stable edges does not
    (a 2:1 rectangle keeps ``2·atan(2)/π`` on its long edges), but a thin part's short edges stop
    being stable (a 3:1 rectangle: ``mu·d = 0.4 · 30 mm > 10 mm``, all mass on the long edges).

Rolling parts (:func:`rolling_density`)
    With friction, a roundish part may have no stable edge at all (every hull edge shorter than
    its foot's shift ``mu·d``: a 48-gon ellipse, a gear): ``r' − side·mu·r`` then keeps one sign
    all round and the part rolls along the fence for as long as it touches it. Where it leaves is
    taken from the stationary density of that rotation, ``∝ 1 / |r' − side·mu·r|``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from feeder.circular import FULL_TURN_DEG, HALF_TURN_DEG, wrap360
from feeder.errors import FeederError
from feeder.mechanics.hull import REL_TOL, as_geometry


@dataclass(frozen=True, eq=False)
class PushFunction:
    """Stable edges of a hull against a fence and their basins in the contact normal ``φ``.

    ``edges``: hull edge indices (increasing normal angle); ``normals_deg``: their outward normals
    (part frame); ``lower_deg``/``upper_deg``: each basin is ``[lower, upper)`` going CCW (upper
    may exceed 360); ``measures``: basin widths / 360, summing to 1. Calling it maps contact
    normals ``φ`` (degrees, any real) to the stable normal their part comes to rest on.

    With friction a roundish part can have no stable edge at all (every edge shorter than the
    foot's shift): it then rolls along the fence for as long as it touches it (``rolls``), and
    :func:`rolling_density` gives where it leaves."""

    edges: np.ndarray
    normals_deg: np.ndarray
    lower_deg: np.ndarray
    upper_deg: np.ndarray
    measures: np.ndarray

    @property
    def rolls(self) -> bool:
        return len(self.edges) == 0

    def basin_index(self, phi_deg) -> np.ndarray:
        """Index (into ``edges``) of the basin holding each ``φ``."""
        if self.rolls:
            raise FeederError("a rolling part has no basins (push_function(...).rolls)")
        phi = np.asarray(phi_deg, dtype=np.float64)
        start = float(self.lower_deg[0])
        rel = wrap360(phi - start)
        bounds = self.upper_deg - start  # increasing, last = 360
        return np.minimum(np.searchsorted(bounds, rel, side="right"), len(self.edges) - 1)

    def __call__(self, phi_deg) -> np.ndarray:
        return self.normals_deg[self.basin_index(phi_deg)]


def contact_patch(part, gap: float) -> tuple[np.ndarray, np.ndarray]:
    """Where each hull edge's contact patch ends, along the edge from its first vertex: the extreme
    positions (``lo <= 0``, ``hi >= length``) of the hull's boundary within ``gap`` of the edge's
    line. The hull is convex, so that part of the boundary is one arc holding the edge: a flat edge
    between sharp corners keeps ``[0, length]`` for a small gap, while an edge of a polygonised
    arc of radius ``R`` gains about ``sqrt(2 R gap)`` each way. ``gap`` 0 gives ``[0, length]``."""
    geom = as_geometry(part)
    gap = float(gap)
    if not (math.isfinite(gap) and gap >= 0.0):
        raise FeederError(f"contact patch gap must be finite and >= 0, got {gap!r}")
    hull = geom.hull
    nxt = np.roll(hull, -1, axis=0)
    e = (nxt - hull) / geom.lengths[:, None]
    normals = np.column_stack([e[:, 1], -e[:, 0]])
    # (edge i, vertex j): depth below edge i's line, and position along edge i from its first vertex
    depth = geom.heights[:, None] - normals @ hull.T
    pos = e @ hull.T - np.sum(e * hull, axis=1)[:, None]
    d_a, d_b = depth, np.roll(depth, -1, axis=1)  # each boundary segment j -> j + 1
    p_a, p_b = pos, np.roll(pos, -1, axis=1)
    # the part of segment j within the gap: depth is linear along it, so clip at depth == gap
    t_cross = np.clip((gap - d_a) / np.where(d_b != d_a, d_b - d_a, 1.0), 0.0, 1.0)
    a_in, b_in = d_a <= gap, d_b <= gap
    q_a = np.where(a_in, p_a, p_a + t_cross * (p_b - p_a))  # the segment's first point within the gap
    q_b = np.where(b_in, p_b, p_a + t_cross * (p_b - p_a))  # its last
    any_in = a_in | b_in
    lo = np.min(np.where(any_in, np.minimum(q_a, q_b), np.inf), axis=1)
    hi = np.max(np.where(any_in, np.maximum(q_a, q_b), -np.inf), axis=1)
    return np.minimum(lo, 0.0), np.maximum(hi, geom.lengths)


def push_function(
    part, mu: float = 0.0, side: int = 1, boundary_mu: float | None = None, patch_gap: float | None = None
) -> PushFunction:
    """The push function of a part's hull against a straight fence (see the module doc).

    ``mu``: part–fence friction coefficient (0: Goldberg's frictionless function); ``side``: +1
    for a fence on the right of the travel direction, −1 on the left (matters only when ``mu >
    0``: the friction shifts the foot downstream); ``boundary_mu``: the friction whose cone turns
    the basin boundaries from the vertex directions (None: ``mu``; another value only to measure
    how much the boundaries matter, docs/experiments/fence_turns.py); ``patch_gap``: the part also
    holds on an edge where the shifted foot lies inside that edge's :func:`contact_patch` of the
    gap (the contact resists a small moment), see :func:`_hold` (None: no patch; measured by
    docs/experiments/fence_turns.py, not a default)."""
    geom = as_geometry(part)
    if not (math.isfinite(mu) and mu >= 0.0):
        raise FeederError(f"fence friction must be finite and >= 0, got {mu!r}")
    if boundary_mu is None:
        boundary_mu = mu
    elif not (math.isfinite(boundary_mu) and boundary_mu >= 0.0):
        raise FeederError(f"boundary friction must be finite and >= 0, got {boundary_mu!r}")
    if side not in (1, -1):
        raise FeederError(f"fence side must be +1 (right) or -1 (left), got {side!r}")
    n = len(geom.hull)
    tol = REL_TOL * geom.circumradius
    shifted = geom.feet + side * mu * geom.heights  # the foot shifted by mu·d downstream
    flow_up_into = shifted > tol  # r' - side·mu·r < 0 just below the normal: φ increases to it
    flow_down_into = shifted < geom.lengths - tol  # > 0 just above: φ decreases to it
    stable = flow_up_into & flow_down_into
    if patch_gap is not None:
        lo, hi = contact_patch(geom, patch_gap)
        hold = (shifted > lo + tol) & (shifted < hi - tol) & ~stable
        if hold.any():
            base = push_function(geom, mu, side, boundary_mu)
            return _hold(geom, base, np.flatnonzero(hold), flow_up_into[0] if base.rolls else True)
    if not stable.any():  # the part rolls: r' - side·mu·r keeps one sign all round
        empty = np.empty(0)
        return PushFunction(np.empty(0, dtype=np.int64), empty, empty, empty, empty)
    lam = math.degrees(math.atan(boundary_mu))
    vert_deg = np.degrees(np.arctan2(geom.hull[:, 1], geom.hull[:, 0]))
    # unstable points: inside vertex j's normal cone [normal(j-1), normal(j)] where the flow turns
    # from decreasing φ (after edge j-1) to increasing φ (before edge j), at the vertex direction
    # turned by -side·λ; or at an edge normal where neither side flows into it
    events: list[tuple[float, int]] = []  # (angle, +1 stable edge index / -1 unstable)
    for i in range(n):
        a = float(geom.normals_deg[i])
        if stable[i]:
            events.append((a, i))
        elif not flow_up_into[i] and not flow_down_into[i]:
            events.append((a, -1))
        j = (i + 1) % n  # the vertex after edge i: its cone runs from normal(i) to normal(j)
        if flow_down_into[i] and flow_up_into[j]:
            width = float(wrap360(geom.normals_deg[j] - a))
            offset = float(wrap360(vert_deg[j] - side * lam - a + HALF_TURN_DEG)) - HALF_TURN_DEG
            events.append((a + min(max(offset, 0.0), width), -1))
    events.sort(key=lambda ev: wrap360(ev[0]))
    stables = [(ang, k) for ang, k in events if k >= 0]
    unstables = np.array([ang for ang, k in events if k < 0], dtype=np.float64)
    m = len(stables)
    edges = np.array([k for _, k in stables], dtype=np.int64)
    normals = np.array([float(wrap360(ang)) for ang, _ in stables])
    # boundary between consecutive stable normals: the (first) unstable point between them
    bounds = np.empty(m)
    for s in range(m):
        lo = normals[s]
        gap = float(wrap360(normals[(s + 1) % m] - lo)) if m > 1 else FULL_TURN_DEG
        rel = wrap360(unstables - lo) if unstables.size else np.empty(0)
        inside = rel[(rel > 0.0) & (rel < gap)] if m > 1 else rel
        bounds[s] = lo + (float(np.min(inside)) if inside.size else 0.5 * gap)
    upper = bounds.copy()  # basin s is [lower[s], upper[s]) and holds normals[s]
    lower = np.roll(bounds, 1)
    lower[0] -= FULL_TURN_DEG  # the last boundary, one turn back
    measures = (upper - lower) / FULL_TURN_DEG
    return PushFunction(edges, normals, lower, upper, measures / measures.sum())


def _hold(geom, base: PushFunction, held: np.ndarray, rolls_up: bool) -> PushFunction:
    """``base`` with the hull edges ``held`` (unstable in it) holding the part: a drop whose contact
    normal lies in a held edge's cell (half way to each neighbouring edge's normal) stays on that
    edge, and a drop flowing towards its basin's stable edge stops on the first held cell in its
    way. A part that rolls in ``base`` rolls towards increasing ``φ`` iff ``rolls_up``."""
    normals = geom.normals_deg
    before = wrap360(normals - np.roll(normals, 1))  # the cone from the previous edge's normal
    after = np.roll(before, -1)
    cell_lo = {int(k): float(normals[k] - 0.5 * before[k]) for k in held}
    cell_hi = {int(k): float(normals[k] + 0.5 * after[k]) for k in held}
    regions: list[tuple[float, float, int]] = []  # (lower, upper, hull edge), unwrapped
    if base.rolls:
        order = sorted((int(k) for k in held), key=lambda k: normals[k])
        for i, k in enumerate(order):
            if rolls_up:  # from the previous held cell's end to this one's
                prev = order[i - 1]
                lo = cell_hi[prev] - (FULL_TURN_DEG if i == 0 else 0.0)
                regions.append((lo, cell_hi[k], k))
            else:
                nxt = order[(i + 1) % len(order)]
                up = cell_lo[nxt] + (FULL_TURN_DEG if i == len(order) - 1 else 0.0)
                regions.append((cell_lo[k], up, k))
    else:
        for s, edge in enumerate(base.edges):
            lo_s, up_s = float(base.lower_deg[s]), float(base.upper_deg[s])
            mid = lo_s + float(wrap360(base.normals_deg[s] - lo_s))
            inside = [(lo_s + float(wrap360(normals[k] - lo_s)), int(k)) for k in held]
            below = sorted((a, k) for a, k in inside if a < mid)
            above = sorted(((a, k) for a, k in inside if mid < a < up_s), reverse=True)
            start = lo_s
            for a, k in below:  # flowing up to the stable edge: stops at the first held cell
                end = min(a + (cell_hi[k] - normals[k]), mid)
                regions.append((start, end, k))
                start = end
            stop = up_s
            tail = []
            for a, k in above:  # flowing down to it
                begin = max(a - (normals[k] - cell_lo[k]), start)
                tail.append((begin, stop, k))
                stop = begin
            regions.append((start, stop, int(edge)))
            regions.extend(reversed(tail))
    regions = [r for r in regions if r[1] > r[0]]
    regions.sort(key=lambda r: float(wrap360(normals[r[2]])))
    edges = np.array([k for _, _, k in regions], dtype=np.int64)
    normal_of = np.array([float(wrap360(normals[k])) for k in edges])
    bounds = normal_of + np.array([float(wrap360(up - normals[k])) for _, up, k in regions])
    upper = bounds.copy()
    lower = np.roll(bounds, 1)
    lower[0] -= FULL_TURN_DEG
    measures = (upper - lower) / FULL_TURN_DEG
    if not np.all(measures > 0.0):  # pragma: no cover - regions partition the turn
        raise FeederError("held basins do not partition the turn")
    return PushFunction(edges, normal_of, lower, upper, measures / measures.sum())


def rolling_density(part, mu: float, side: int, phi_deg) -> np.ndarray:
    """Weights (summing to 1) of contact normals ``φ`` at which a rolling part (no stable edge)
    leaves a long fence: the flow ``dφ/dτ ∝ −g(φ)``, ``g = r'(φ) − side·mu·r(φ)``, spends time
    ``∝ 1/|g|`` at each ``φ``, its stationary density."""
    geom = as_geometry(part)
    phi = np.radians(np.asarray(phi_deg, dtype=np.float64))
    u = np.stack([np.cos(phi), np.sin(phi)], axis=-1)
    support = geom.hull[np.argmax(u @ geom.hull.T, axis=-1)]
    r = np.sum(support * u, axis=-1)
    dr = support[..., 1] * u[..., 0] - support[..., 0] * u[..., 1]  # support · (−sin φ, cos φ)
    g = np.abs(dr - side * mu * r)
    w = 1.0 / np.maximum(g, REL_TOL * geom.circumradius)
    return w / w.sum()
