"""How fast a fence turns a part: the turn per unit push at each contact normal.

A fence that pushes a part sideways by an overlap ``o`` turns it by at most ``o / (2c)``
(:mod:`feeder.mechanics.distribution`, the turn budget): a unit push whose line of force passes
at a moment arm ``a`` from the centroid turns the part by ``a / (c² + a²)``, largest at ``a = c``.
A part whose line of force passes close to its centroid turns much slower than that bound. On a
round stretch of hull (many short edges, none quite stable under the fence's friction) the line
passes within a fraction of a millimetre of the centroid, and the part keeps the yaw it arrived
with: crescent-b on ``straight:15`` keeps its yaw over about 30° of its outer arc in the
simulator and stops there when it comes from a further 200°, where the push function (which knows
only the direction of the turn) sends every drop round to the chord between its horns.

:func:`turn_rates` gives the rate of each contact normal ``φ`` (part frame, the normal pointing at
the fence) against a straight fence face at local angle ``α``: the part's hull touches the face at
its support vertex, pushed quasi-statically with the ellipsoidal limit surface and Coulomb
friction, sticking or sliding (:func:`feeder.mechanics.arcride.contact_twists`, the arc ride's
contact, here against the straight face), as the turn rate per unit normal push relative to the
bound ``1 / (2c)`` (1 for a frictionless push at ``a = c``; 0 where the line of force passes
through the centroid). :class:`TurnCost` integrates it: the budget it takes to turn from one
``φ`` to another is ``∫ dφ / q(φ)`` in the budget's own units (degrees at the bound's rate).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from feeder.circular import FULL_TURN_DEG, wrap360
from feeder.errors import FeederError
from feeder.mechanics.arcride import contact_twists
from feeder.mechanics.fence import fence_normal_deg
from feeder.mechanics.hull import as_geometry

# Grid of contact normals over which the rate is integrated (degrees between nodes)
TURN_RATE_STEP_DEG = 0.02
# Smallest rate kept (relative to the bound): where the line of force passes through the centroid the
# rate is 0 and the part would need an infinite push; a 0.02° step then costs 200 degrees of budget
TURN_RATE_FLOOR = 1e-4
_PUSHER = np.array([0.0, -1.0])  # the fence's velocity relative to the belt (belt frame)
# Turns covered by the table, from -1 turn: a basin (at most one turn wide, from its lower bound at
# or above -1 turn) and any target in it lie in [-1, 2) turns
_TURNS = 3


def turn_rates(part, fence_angle_deg: float, side: int, mu: float, phi_deg) -> np.ndarray:
    """Turn rate (per unit push along the face's normal, relative to ``1 / (2c)``, ``c`` the
    limit-surface radius) of a part touching a straight fence face of local angle
    ``fence_angle_deg`` on ``side`` (+1 right of the travel direction) with contact normal
    ``phi_deg`` (part frame), part–fence friction ``mu``. Non-negative: the direction of the turn
    is the push function's."""
    geom = as_geometry(part)
    if not (math.isfinite(mu) and mu >= 0.0):
        raise FeederError(f"fence friction must be finite and >= 0, got {mu!r}")
    if side not in (1, -1):
        raise FeederError(f"fence side must be +1 (right) or -1 (left), got {side!r}")
    phi = np.radians(np.asarray(phi_deg, dtype=np.float64).ravel())
    u = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    support = geom.hull[np.argmax(u @ geom.hull.T, axis=1)]  # the vertex touching the face
    normal = math.radians(float(fence_normal_deg(fence_angle_deg, side)))
    yaw = normal - phi  # the part's yaw when its normal phi points at the face
    cs, sn = np.cos(yaw), np.sin(yaw)
    r = np.stack([cs * support[:, 0] - sn * support[:, 1], sn * support[:, 0] + cs * support[:, 1]], axis=1)
    n = np.broadcast_to(-np.array([math.cos(normal), math.sin(normal)]), r.shape)  # into the part
    c = float(geom.limit_radius)
    twist = contact_twists(r, np.ascontiguousarray(n), float(mu), c * c)
    push = float(n[0] @ _PUSHER) if len(n) else 1.0  # the face's advance along its normal, per unit travel
    if push <= 0.0:
        raise FeederError(f"a fence face at {fence_angle_deg}° does not advance on the part: no turn rate")
    rate = 2.0 * c * np.abs(twist[:, 2]) / push
    return rate.reshape(np.shape(phi_deg))


@dataclass(frozen=True, eq=False)
class TurnCost:
    """The budget it takes to turn between contact normals on one fence face: ``grid_deg``, nodes
    from −1 turn over three turns; ``cost``, the cumulative ``∫ dφ / q(φ)`` at each node (degrees
    of budget, increasing)."""

    grid_deg: np.ndarray
    cost: np.ndarray

    def between(self, phi_from, phi_to) -> np.ndarray:
        """Budget needed to turn from ``phi_from`` to ``phi_to`` (degrees, in [−1, 2) turns)."""
        a = np.interp(phi_from, self.grid_deg, self.cost)
        b = np.interp(phi_to, self.grid_deg, self.cost)
        return np.abs(b - a)

    def advance(self, phi_from, direction, budget) -> np.ndarray:
        """The contact normal reached from ``phi_from`` turning in ``direction`` (±1) on
        ``budget`` degrees of budget (not past the table's ends)."""
        a = np.interp(phi_from, self.grid_deg, self.cost)
        return np.interp(a + np.sign(direction) * np.asarray(budget), self.cost, self.grid_deg)


def turn_cost(part, fence_angle_deg: float, side: int, mu: float) -> TurnCost:
    """The :class:`TurnCost` of a part against one straight fence face (:func:`turn_rates`,
    integrated by the midpoint rule on ``TURN_RATE_STEP_DEG``, rates floored at
    ``TURN_RATE_FLOOR``)."""
    per_turn = int(round(FULL_TURN_DEG / TURN_RATE_STEP_DEG))
    step = FULL_TURN_DEG / per_turn
    mids = (np.arange(per_turn) + 0.5) * step
    q = np.maximum(turn_rates(part, fence_angle_deg, side, mu, mids), TURN_RATE_FLOOR)
    cell = np.tile(step / q, _TURNS)
    grid = -FULL_TURN_DEG + np.arange(_TURNS * per_turn + 1) * step
    cost = np.concatenate([[0.0], np.cumsum(cell)])
    return TurnCost(grid, cost)


def unwrap_into(phi_deg, lower_deg) -> np.ndarray:
    """``phi_deg`` moved by whole turns into ``[lower, lower + 360)``."""
    lo = np.asarray(lower_deg, dtype=np.float64)
    return lo + wrap360(np.asarray(phi_deg, dtype=np.float64) - lo)
