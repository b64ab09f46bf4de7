"""A part riding a curved fence's arc: where it has turned to by the time it reaches the tip.

The analytic model takes a curved fence as the straight fence of its last chord: the push
function at the exit angle picks each drop's basin from the yaw it arrives with
(:mod:`feeder.mechanics.distribution`). A part meets the arc where it is steeper, starts turning
there towards the stable edge of that angle, and keeps turning as the arc flattens under it, so
by the tip it may lie in another basin of the exit chord than the one it arrived in.

:func:`arc_yaw` integrates that ride: the part's convex hull pushed by the circle of the arc's
outer face (only over the arc's span: the round tip and the part past it are the exit turn's),
quasi-static with the ellipsoidal limit surface ``(v, ω) ∝ (F, r × F / c²)`` and Coulomb
friction at the one contact, sticking or sliding on the cone edge that opposes the slip (as
:func:`feeder.mechanics.exitturn._contact_twist`, vectorised over drops), the belt carrying the
part at unit speed along +y past the fixed fence. It returns the yaw at the last step the arc
pushed each drop. A circle stands in for the simulator's 16 chords (their sagitta is 0.24 mm on
the study's 0.2 m radius).
"""

from __future__ import annotations

import math

import numpy as np

from feeder.errors import FeederError
from feeder.mechanics.fence import FenceModel
from feeder.mechanics.hull import as_geometry

# Belt travel per integration step in contact: the hull's circumradius / this (100 moves 1.5 % of the
# ridden yaws of four library parts on curved:10-80 by more than 1 deg, at twice the cost)
ARC_STEPS_PER_RADIUS = 50
ARC_MAX_TRAVEL_RADII = 400.0  # belt travel (circumradii) after which the ride stops
ARC_STALL_RADII = 0.05  # a drop that moves downstream less than this (circumradii) over one circumradius
# of belt travel is held by the arc: its ride stops there
# Quantisation of the arriving states ridden (drops closer than this share one ride): yaw, lateral position
ARC_YAW_QUANTUM_DEG = 0.5
ARC_X_QUANTUM_RADII = 0.01
_PUSHER = np.array([0.0, -1.0])  # the fence's velocity relative to the belt (belt frame)


def _closest_on_polygons(verts: np.ndarray, centre: np.ndarray):
    """Closest point of each closed polygon ``verts`` (N, V, 2) to the point ``centre`` (2,):
    the points (N, 2) and their distances (N,)."""
    b = np.roll(verts, -1, axis=1)
    ab = b - verts
    rel = centre[None, None, :] - verts
    t = np.einsum("nvk,nvk->nv", rel, ab) / np.maximum(np.einsum("nvk,nvk->nv", ab, ab), 1e-300)
    p = verts + np.clip(t, 0.0, 1.0)[..., None] * ab
    d = np.hypot(p[..., 0] - centre[0], p[..., 1] - centre[1])
    i = np.argmin(d, axis=1)
    rows = np.arange(len(verts))
    return p[rows, i], d[rows, i]


def contact_twists(r: np.ndarray, n: np.ndarray, mu: float, c2: float) -> np.ndarray:
    """Twists ``(vx, vy, ω)`` (belt frame, per unit pusher travel) of parts pushed at ``r`` (N, 2;
    from the centroid) through contacts of inward normal ``n`` (N, 2; unit) by a pusher moving
    at (0, −1) relative to the belt, quasi-static with the ellipsoidal limit surface of
    ``c2 = c²``: sticking where the pusher's velocity lies in the motion cone, else sliding on the
    friction-cone edge that opposes the slip; zero where the pusher moves away from the contact."""
    e = np.stack([-n[:, 1], n[:, 0]], axis=1)
    vpn = n @ _PUSHER
    perp = np.stack([-r[:, 1], r[:, 0]], axis=1)
    edges = []
    for s in (1.0, -1.0):
        f = n + s * mu * e
        w = (r[:, 0] * f[:, 1] - r[:, 1] * f[:, 0]) / c2
        edges.append((s, f, w, f + w[:, None] * perp))  # force, turn rate, contact velocity per unit
    (_, f1, w1, v1), (_, f2, w2, v2) = edges
    out = np.zeros((len(r), 3))
    det = v1[:, 0] * v2[:, 1] - v1[:, 1] * v2[:, 0]
    safe = np.where(det != 0.0, det, 1.0)
    k1 = (_PUSHER[0] * v2[:, 1] - _PUSHER[1] * v2[:, 0]) / safe
    k2 = (v1[:, 0] * _PUSHER[1] - v1[:, 1] * _PUSHER[0]) / safe
    stick = (det != 0.0) & (k1 >= 0.0) & (k2 >= 0.0) & (vpn > 0.0)
    out[stick, :2] = k1[stick, None] * f1[stick] + k2[stick, None] * f2[stick]
    out[stick, 2] = k1[stick] * w1[stick] + k2[stick] * w2[stick]
    done = stick | (vpn <= 0.0)
    for s, f, w, v in edges:
        vn = np.einsum("nk,nk->n", v, n)
        k = vpn / np.where(vn > 0.0, vn, 1.0)
        slip = np.einsum("nk,nk->n", k[:, None] * v - _PUSHER, e)
        ok = ~done & (vn > 0.0) & (s * slip <= 0.0)
        out[ok, :2] = k[ok, None] * f[ok]
        out[ok, 2] = k[ok] * w[ok]
        done |= ok
    return out


def arc_span_deg(model: FenceModel) -> tuple[float, float]:
    """Polar angles (degrees, about the arc's centre) of the arc's tip and of its slot end; the
    arc runs from the slot end towards the tip clockwise on the right (+1), counterclockwise on
    the left, over the angle between its slot and exit chords."""
    if not model.curved:
        raise FeederError(f"fence {model.fence} is not curved: it has no arc to ride")
    tip = math.degrees(math.atan2(model.tip[1] - model.centre[1], model.tip[0] - model.centre[0]))
    return tip, tip + model.side * (model.slot_deg - model.exit_deg)


def _ride(geom, model: FenceModel, yaw_deg: np.ndarray, x: np.ndarray, mu: float) -> np.ndarray:
    n = len(yaw_deg)
    hull = np.asarray(geom.hull, dtype=np.float64)
    c = float(geom.circumradius)
    c2 = float(geom.limit_radius) ** 2
    ds = c / ARC_STEPS_PER_RADIUS
    centre = np.asarray(model.centre, dtype=np.float64)
    ro = float(model.outer_radius)
    tip_deg, slot_deg = arc_span_deg(model)
    span = math.radians(abs(slot_deg - tip_deg))
    slot = math.radians(slot_deg)
    sweep = slot - model.side * np.linspace(0.0, span, 181)
    top = float(np.max(centre[1] + ro * np.sin(sweep)))  # the arc's most downstream point
    ends = [centre + ro * np.array([math.cos(a), math.sin(a)]) for a in (sweep[0], sweep[-1])]

    def along(pts: np.ndarray) -> np.ndarray:  # polar angle of points about the centre, from the slot end
        return (
            np.mod(
                model.side * (slot - np.arctan2(pts[:, 1] - centre[1], pts[:, 0] - centre[0])) + math.pi, 2.0 * math.pi
            )
            - math.pi
        )

    yaw = np.radians(yaw_deg)
    pos = np.stack([x, np.full(n, centre[1] - ro - 2.0 * c)], axis=1)  # just upstream of the arc
    out = np.full(n, np.nan)
    active = np.ones(n, dtype=bool)
    steps = int(ARC_MAX_TRAVEL_RADII * ARC_STEPS_PER_RADIUS)
    mark = pos[:, 1].copy()
    for step in range(1, steps + 1):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        cs, sn = np.cos(yaw[idx])[:, None], np.sin(yaw[idx])[:, None]
        verts = pos[idx, None, :] + np.stack(
            [cs * hull[None, :, 0] - sn * hull[None, :, 1], sn * hull[None, :, 0] + cs * hull[None, :, 1]], axis=2
        )
        p, d = _closest_on_polygons(verts, centre)
        on = along(p)
        contact = (d < ro) & (on >= 0.0) & (on <= span)
        v = np.zeros((idx.size, 3))
        if contact.any():
            k = np.flatnonzero(contact)
            nrm = (p[k] - centre) / d[k, None]
            v[k] = contact_twists(p[k] - pos[idx[k]], nrm, mu, c2)
            pos[idx[k]] += (ro - d[k])[:, None] * nrm  # back onto the face
            out[idx[k]] = yaw[idx[k]]
        v[:, 1] += 1.0  # the belt carries the part past the fixed fence
        # free of the arc, a part travels at least as far as its circumscribed disc is from the arc
        travel = np.full(idx.size, ds)
        free = ~contact
        if free.any():
            at = pos[idx[free]]
            r = np.hypot(at[:, 0] - centre[0], at[:, 1] - centre[1])
            on_c = along(at)
            inside = (on_c >= 0.0) & (on_c <= span)
            gap = np.where(
                inside,
                np.abs(r - ro),
                np.minimum(np.hypot(*(pos[idx[free]] - ends[0]).T), np.hypot(*(pos[idx[free]] - ends[1]).T)),
            )
            travel[free] = np.maximum(ds, gap - c)
        pos[idx] += v[:, :2] * travel[:, None]
        yaw[idx] += v[:, 2] * travel
        gone = ~contact & (verts[:, :, 1].min(axis=1) > top)
        active[idx[gone]] = False
        if step % ARC_STEPS_PER_RADIUS == 0:  # held in place: stop riding
            active &= pos[:, 1] - mark >= ARC_STALL_RADII * c
            mark = pos[:, 1].copy()
    return np.degrees(out)


def arc_yaw(part, model: FenceModel, yaw_deg, x, mu: float, memo: dict | None = None) -> np.ndarray:
    """Yaw (degrees, [0, 360)) of each drop (part-frame yaw ``yaw_deg``, lateral centroid position
    ``x`` in metres) at the last step the arc of the curved fence ``model`` pushed it; NaN for a
    drop the arc never touches. Drops within ``ARC_YAW_QUANTUM_DEG`` and ``ARC_X_QUANTUM_RADII``
    of each other share one ride (the arriving states of a configuration are a few hundred).
    ``memo``: a dict kept for this one part, filled with the rides and reused (each state's ride
    does not depend on the others ridden with it)."""
    geom = as_geometry(part)
    yaw = np.mod(np.asarray(yaw_deg, dtype=np.float64), 360.0)
    xs = np.broadcast_to(np.asarray(x, dtype=np.float64), yaw.shape)
    if not (math.isfinite(mu) and mu >= 0.0):
        raise FeederError(f"fence friction must be finite and >= 0, got {mu!r}")
    if yaw.size == 0:
        return yaw.copy()
    qy = np.rint(yaw / ARC_YAW_QUANTUM_DEG).astype(np.int64) % int(round(360.0 / ARC_YAW_QUANTUM_DEG))
    qx = np.rint(xs / (ARC_X_QUANTUM_RADII * geom.circumradius)).astype(np.int64)
    keys, inverse = np.unique(np.stack([qy, qx], axis=1), axis=0, return_inverse=True)
    known = {} if memo is None else memo.setdefault(("arc_ride", model, float(mu)), {})
    todo = [i for i, k in enumerate(map(tuple, keys.tolist())) if k not in known]
    if todo:
        rode = _ride(
            geom,
            model,
            keys[todo, 0] * ARC_YAW_QUANTUM_DEG,
            keys[todo, 1] * ARC_X_QUANTUM_RADII * geom.circumradius,
            float(mu),
        )
        known.update(zip(map(tuple, keys[todo].tolist()), rode.tolist()))
    rode = np.array([known[k] for k in map(tuple, keys.tolist())], dtype=np.float64)
    return np.mod(rode[inverse.reshape(-1)], 360.0)
