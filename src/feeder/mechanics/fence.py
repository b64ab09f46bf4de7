"""A fence as the analytic model sees it: the orientation of its face, its friction cone, and
the fences of a configuration in the order a part meets them.

Jams
    A part slides along a fence face only outside the friction cone: the belt velocity makes the
    angle ``β = 90° − α`` with the face normal (``α`` the local fence angle), and quasi-static
    equilibrium of belt drag, normal force and Coulomb friction along the face gives a sliding
    speed ``v (sin β − mu cos β)``, positive iff ``tan β > mu``, i.e. ``α < 90° − atan(mu)``
    (68.2° with the scene's part–fence ``mu = 0.8 × 0.5 = 0.4``, Bullet multiplying the two
    coefficients; the belt's own friction cancels out). The signed margin
    ``90° − atan(mu) − α`` is a feature per fence (straight: ``α = θ``; curved: the mean entry
    angle of the drops that touch it), and a drop whose entry angle lies in the cone is counted
    as jammed (removed from the PMF, which is over ok drops as the labels are). Against
    ``results/tables/jam_rates.csv`` (``feeder bench-jams``, one fence alone, 8 parts x 42 fence
    rows): jammed share > 0.5 predicted right in 90 % of rows; curved 60/70 jam (predicted), 80/90
    do not (grazed); missed: straight 65° (margin +3.2°, yet 55 % jam: a slide slower than
    ``status.jam_travel / jam_window_s`` = 5 mm/s counts as jammed, and ``v (sin β − mu cos β)``
    is 6 mm/s there) and the 10–25 % of drops that jam on curved 30–50 (predicted 0 below 50°).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from feeder.circular import wrap360
from feeder.lane.fences import Fence, parse_location
from feeder.lane.geometry import box_corners, curved_polyline, scene_fences
from feeder.lane.settings import load_settings

RIGHT_ANGLE_DEG = 90.0


def fence_normal_deg(fence_angle_deg, side: int) -> np.ndarray:
    """World direction (degrees) of the outward normal of a part edge lying flush on a fence face
    whose local angle to the travel direction is ``fence_angle_deg`` on ``side`` (+1 right)."""
    a = np.radians(np.asarray(fence_angle_deg, dtype=np.float64))
    return wrap360(np.degrees(np.arctan2(np.sin(a), side * np.cos(a))))


def resting_yaw(edge_normal_deg, fence_angle_deg, side: int) -> np.ndarray:
    """Part-frame yaw (degrees, [0, 360)) at which the edge of part-frame outward normal
    ``edge_normal_deg`` lies flush on the fence: its normal then points at the fence."""
    return wrap360(fence_normal_deg(fence_angle_deg, side) - np.asarray(edge_normal_deg, dtype=np.float64))


def friction_margin_deg(fence_angle_deg, mu: float) -> np.ndarray:
    """``90° − atan(mu) − α``: positive where a part slides along a face at local angle ``α``,
    negative inside the friction cone (the part sticks: a jam)."""
    return RIGHT_ANGLE_DEG - math.degrees(math.atan(mu)) - np.asarray(fence_angle_deg, dtype=np.float64)


@lru_cache(maxsize=1)
def default_scene() -> dict:
    """The ``scene`` section of the study config (``config/config.yaml``), read once."""
    return load_settings()[0]


def fence_mu(scene: dict) -> float:
    """Part–fence friction as pybullet combines it: ``scene.part.friction × scene.fences.friction``."""
    return float(scene["part"]["friction"]) * float(scene["fences"]["friction"])


@dataclass(frozen=True)
class FenceModel:
    """One built fence as the analytic model sees it (lane coordinates, metres, degrees).

    ``side``: +1 right, −1 left; ``inner``: innermost reach ``min(side · x)`` of its footprint;
    ``exit_deg``: local angle of the face the part leaves from (straight: θ; curved: last chord);
    ``slot_deg``: local angle at the slot end (straight: θ); ``tip``: the corner the part leaves
    around; ``centre``/``outer_radius``: the arc of a curved fence's face (None for straight);
    ``cap``/``cap_radius``: a round tip's cylinder, centre and radius (None and 0 for a square
    tip): the part leaves around it, not around ``tip``."""

    location: str
    fence: Fence
    side: int
    inner: float
    exit_deg: float
    slot_deg: float
    tip: tuple[float, float]
    centre: tuple[float, float] | None = None
    outer_radius: float | None = None
    cap: tuple[float, float] | None = None
    cap_radius: float = 0.0

    @property
    def curved(self) -> bool:
        return self.centre is not None


def _local_angle(yaw_rad: float, side: int) -> float:
    """Local fence angle (degrees, to the travel direction) of a box running along ``yaw_rad``
    from the slot towards the tip."""
    return math.degrees(math.atan2(-side * math.cos(yaw_rad), math.sin(yaw_rad)))


def fence_models(loc1, loc2, scene: dict | None = None) -> list[FenceModel]:
    """The fences of a configuration in the order a part meets them (Location 2, then 1), built
    by the simulator's own geometry (:func:`feeder.sim.scene.scene_fences`, with the upstream
    fence trimmed to ``min_gap``). A round tip (``scene.fences.tip``) keeps its cylinder (``cap``): the
    exit turn runs around it (:func:`feeder.mechanics.distribution.fence_response`)."""
    scene = default_scene() if scene is None else scene
    loc1, loc2 = as_fence(loc1), as_fence(loc2)
    out = []
    for fg in scene_fences(scene, loc1, loc2):
        side = fg.side
        corners = np.concatenate([box_corners(*b) for b in fg.boxes])
        inner = float(np.min(side * corners[:, 0]))
        cx, cy, hl, ht, yaw = fg.boxes[-1]
        d = np.array([math.cos(yaw), math.sin(yaw)])
        face = np.array([-d[1], d[0]])
        face = face if face[1] < 0 else -face  # the face the part meets is on the upstream side
        tip = np.array([cx, cy]) + hl * d + ht * face
        exit_deg = _local_angle(yaw, side)
        slot_deg = _local_angle(fg.boxes[0][4], side)
        centre = radius = None
        if fg.fence.type == "curved":
            fc = scene["fences"]
            cc = fc["curved"]
            slot_x = float(fc["slots"][cc["slot"]])
            y0 = float(fc["locations"][fg.location]["y"])
            _, ctr = curved_polyline(
                fg.fence.angle, side, slot_x, y0, float(cc["radius"]), float(cc["span_deg"]), int(cc["segments"])
            )
            centre = (float(ctr[0]), float(ctr[1]))
            radius = float(cc["radius"]) + float(ht)
        cap = fg.tip_cap()
        out.append(
            FenceModel(
                fg.location,
                fg.fence,
                side,
                inner,
                exit_deg,
                slot_deg,
                (float(tip[0]), float(tip[1])),
                centre,
                radius,
                None if cap is None else (float(cap[0]), float(cap[1])),
                0.0 if cap is None else float(cap[2]),
            )
        )
    return out


def as_fence(loc) -> Fence:
    return loc if isinstance(loc, Fence) else parse_location(loc)
