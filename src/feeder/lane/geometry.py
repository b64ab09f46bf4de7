"""The fences as built in the lane: boxes in lane coordinates, from the ``scene`` config section.

Coordinates (one *lane*, i.e. one belt with its walls and fences): the belt surface is the plane
``z = 0``, parts travel along ``+y`` at ``belt.speed`` and ``x`` is across the belt, ``+x`` on the
right-hand side of the direction of travel. Location 1 (downstream, ``y = 1.0``) is on the right,
Location 2 (upstream, ``y = 0.5``) on the left (``scene.mirror`` swaps the sides).

Fences (all sizes in the config, none in code):

* **straight** at angle θ (between the fence and the direction of travel, 0 < θ < 90): a cuboid
  whose wall end is at the slot ``(±slot_x, y0)`` (it continues into the wall, so nothing passes
  behind it) and which runs downstream and inward at θ. Its length is chosen per angle so that its
  free tip lies ``tip_past_centre`` beyond the belt centre line, where parts travel: every angle
  sweeps the whole part lane (capped at ``max_length`` for tiny angles).
* **curved** at angle θ (0 ≤ θ ≤ 90): an arc of radius ``r`` through the slot point
  ``P0 = (±slot_x, y0)`` with centre ``C = (x0 − r·sin θ, y0 + r·cos θ)`` (the placement formula
  of the paper, mirrored for the left side), i.e. a fixed arc rotated about ``P0`` by θ. The arc
  leaves ``P0`` inward and spans ``span_deg``; it is built from ``segments`` boxes along the arc.

With both locations in use, the upstream fence is cut back from its tip until it keeps
``fences.min_gap`` from the downstream one (:func:`trim_to_gap`): a shallow upstream fence and a
downstream one that both reach past the centre line would otherwise cross, and the closed V they
form traps every part that enters it.

A fence is a list of boxes ``(cx, cy, half_length, half_thickness, yaw)``; its footprint is a
shapely polygon used to decide what a part's lane can reach.

Everything here is a pure function of the scene settings; the simulator (:mod:`feeder.sim`) builds
these boxes as bodies and the analytic mechanics (:mod:`feeder.mechanics`) push parts along them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from feeder.errors import FeederError
from feeder.lane.fences import Fence

FENCE_TIPS = ("square", "round")  # scene.fences.tip
CURVED_BUILDS = ("boxes", "hull")  # scene.fences.curved.build
_CAP_QUAD_SEGS = 16  # segments per quarter circle of a round tip's disc in a footprint


# --------------------------------------------------------------------------------------------
# Fence geometry
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FenceGeom:
    """One built fence: boxes ``(cx, cy, half_length, half_thickness, yaw_rad)`` in lane coords."""

    location: str
    fence: Fence
    side: int  # +1 right (x > 0), -1 left
    boxes: tuple[tuple[float, float, float, float, float], ...]
    round_tip: bool = False  # scene.fences.tip: round (a cylinder caps the free end)

    def tip_cap(self) -> tuple[float, float, float] | None:
        """``(x, y, radius)`` of the vertical cylinder that caps a round tip: centred on the end of
        the last box's centre line, of the box's half thickness, so the face runs smoothly into it;
        None for a square tip (or no box left)."""
        if not self.round_tip or not self.boxes:
            return None
        cx, cy, hl, ht, yaw = self.boxes[-1]
        return (cx + hl * math.cos(yaw), cy + hl * math.sin(yaw), ht)

    def footprint(self):
        """Union of the boxes' footprints (shapely), with the round tip's disc."""
        from shapely.geometry import Point, Polygon
        from shapely.ops import unary_union

        shapes = [Polygon(box_corners(*b)) for b in self.boxes]
        cap = self.tip_cap()
        if cap is not None:
            shapes.append(Point(cap[0], cap[1]).buffer(cap[2], quad_segs=_CAP_QUAD_SEGS))
        return unary_union(shapes)

    @property
    def length(self) -> float:
        return float(sum(2.0 * b[2] for b in self.boxes))


def fence_tip(scene: dict) -> str:
    """``scene.fences.tip``: ``square`` (the box's end, the default when the key is absent) or
    ``round`` (a cylinder of the fence's half thickness caps its free end). Bullet pushes past a
    square tip's corner with the face's normal (docs/simulation.md, "A square fence tip")."""
    tip = scene["fences"].get("tip", "square")
    if tip not in FENCE_TIPS:
        raise FeederError(f"scene.fences.tip must be one of {', '.join(FENCE_TIPS)}, got {tip!r}")
    return tip


def box_corners(cx, cy, hl, ht, yaw) -> np.ndarray:
    """Corners (4, 2) CCW of a rectangle of half sizes (hl along yaw, ht across) centred at (cx, cy)."""
    c, s = math.cos(yaw), math.sin(yaw)
    u, v = np.array([c, s]), np.array([-s, c])
    ctr = np.array([cx, cy])
    return np.array([ctr - hl * u - ht * v, ctr + hl * u - ht * v, ctr + hl * u + ht * v, ctr - hl * u + ht * v])


def segment_box(p, q, half_thickness: float, extend: float = 0.0):
    """Box along the segment p→q (extended by ``extend`` at both ends)."""
    p, q = np.asarray(p, float), np.asarray(q, float)
    d = q - p
    length = float(np.hypot(*d))
    yaw = math.atan2(d[1], d[0])
    mid = 0.5 * (p + q)
    return (float(mid[0]), float(mid[1]), 0.5 * length + extend, half_thickness, yaw)


def straight_length(theta_deg: float, slot_x: float, tip_past_centre: float, max_length: float) -> float:
    """Length from the slot to the tip of a straight fence at θ (tip ``tip_past_centre`` past x = 0)."""
    s = math.sin(math.radians(theta_deg))
    return min(max_length, (slot_x + tip_past_centre) / s)


def straight_polyline(theta_deg, side, slot_x, y0, tip_past_centre, max_length, wall_x):
    """Centre line of a straight fence: from inside the wall (x = ±wall_x) through the slot to the tip."""
    th = math.radians(theta_deg)
    d = np.array([-side * math.sin(th), math.cos(th)])  # downstream and inward
    anchor = np.array([side * slot_x, y0])
    length = straight_length(theta_deg, slot_x, tip_past_centre, max_length)
    back = (wall_x - slot_x) / math.sin(th)  # extend back into the wall
    return np.array([anchor - back * d, anchor + length * d])


def curved_polyline(theta_deg, side, slot_x, y0, radius, span_deg, segments, offset=0.0):
    """Points along a curved fence's arc (radius ``radius``): centre per the placement formula.

    Right-side frame: centre ``C = (x0 - r sin θ, y0 + r cos θ)``; the arc starts at the slot
    point (polar angle θ - 90° seen from C) and runs clockwise (inward) over ``span_deg``. The
    left side is the mirror image. Points lie at ``radius + offset`` from the centre (offset: the
    outer face of a fence of that half thickness). Returns (segments + 1, 2) points and the centre.
    """
    th = math.radians(theta_deg)
    cx, cy = slot_x - radius * math.sin(th), y0 + radius * math.cos(th)  # right-side frame
    phi0 = th - math.pi / 2.0  # polar angle of the slot point seen from the centre
    phis = phi0 - np.linspace(0.0, math.radians(span_deg), segments + 1)  # clockwise: inward
    ro = radius + offset
    pts = np.stack([cx + ro * np.cos(phis), cy + ro * np.sin(phis)], axis=1)
    pts[:, 0] *= side
    return pts, np.array([side * cx, cy])


def arc_boxes(pts_outer: np.ndarray, centre: np.ndarray, half_thickness: float):
    """Boxes whose outer faces are the chords of ``pts_outer`` (points on the outer circle).

    Parts touch the convex (outer) side, which is then a convex chain without steps; the boxes
    overlap only on the inner side.
    """
    boxes = []
    for a, b in zip(pts_outer[:-1], pts_outer[1:]):
        mid = 0.5 * (a + b)
        out = mid - centre
        out = out / np.hypot(*out)
        cx, cy, hl, _, yaw = segment_box(a, b, half_thickness)
        boxes.append(
            (float(mid[0] - half_thickness * out[0]), float(mid[1] - half_thickness * out[1]), hl, half_thickness, yaw)
        )
    return tuple(boxes)


def location_side(location: str, mirror: bool) -> int:
    side = {"loc1": 1, "loc2": -1}[location]
    return -side if mirror else side


def fence_geometry(scene: dict, location: str, fence: Fence) -> FenceGeom | None:
    """The boxes of the fence at ``location`` ('loc1'/'loc2'), or None for 'none'."""
    if not fence.present:
        return None
    fc = scene["fences"]
    side = location_side(location, bool(scene.get("mirror", False)))
    y0 = float(fc["locations"][location]["y"])
    ht = 0.5 * float(fc["thickness"])
    if fence.type == "straight":
        sc = fc["straight"]
        slot_x = float(fc["slots"][sc["slot"]])
        wall_x = float(scene["belt"]["half_width"]) + 0.5 * float(scene["walls"]["thickness"])
        pts = straight_polyline(
            fence.angle, side, slot_x, y0, float(sc["tip_past_centre"]), float(sc["max_length"]), wall_x
        )
        boxes = (segment_box(pts[0], pts[1], ht),)
    else:
        pts, centre = curved_outer_points(scene, location, fence)
        boxes = arc_boxes(pts, centre, ht)
    return FenceGeom(location, fence, side, boxes, fence_tip(scene) == "round")


def curved_outer_points(scene: dict, location: str, fence: Fence) -> tuple[np.ndarray, np.ndarray]:
    """The curved fence at ``location``: the ``segments`` + 1 points of its outer face (the arc,
    radius r, is the fence's centre line; its outer face lies at r + thickness / 2) and the arc's
    centre, in lane coordinates."""
    fc, cc = scene["fences"], scene["fences"]["curved"]
    side = location_side(location, bool(scene.get("mirror", False)))
    y0 = float(fc["locations"][location]["y"])
    ht = 0.5 * float(fc["thickness"])
    slot_x = float(fc["slots"][cc["slot"]])
    return curved_polyline(
        fence.angle, side, slot_x, y0, float(cc["radius"]), float(cc["span_deg"]), int(cc["segments"]), offset=ht
    )


def curved_build(scene: dict) -> str:
    """``scene.fences.curved.build``: how the simulator builds a curved fence. ``boxes`` (the default
    when the key is absent): one box per chord, whose seams catch sharp parts (docs/simulation.md,
    "The seams between a fence's boxes catch sharp parts"). ``hull``: one convex piece, the hull of
    its outer face (no seam on the face; the segment behind the arc filled)."""
    build = scene["fences"]["curved"].get("build", "boxes")
    if build not in CURVED_BUILDS:
        raise FeederError(f"scene.fences.curved.build must be one of {', '.join(CURVED_BUILDS)}, got {build!r}")
    if build == "hull" and int(scene["fences"]["curved"]["segments"]) < 2:  # one chord: a flat sheet
        raise FeederError("scene.fences.curved.build: hull needs segments >= 2 (one chord has no thickness)")
    return build


def trim_to_gap(up: FenceGeom, down: FenceGeom, gap: float, tol: float = 1e-4) -> FenceGeom:
    """``up`` shortened from its free tip until its footprint is at least ``gap`` from ``down``.

    Two fences from opposite sides that both reach past the centre line can cross (e.g. a long
    upstream fence at 15° and a downstream one at 30°): their V is a trap that jams every part
    entering it, which no feeder would be built with. A straight fence keeps its wall end and
    loses length (bisection to ``tol``); a curved fence loses whole boxes from its tip.
    """
    target = down.footprint()
    if up.footprint().distance(target) >= gap:
        return up

    def with_boxes(boxes):
        return FenceGeom(up.location, up.fence, up.side, tuple(boxes), up.round_tip)

    if up.fence.type == "curved":
        boxes = list(up.boxes)
        while boxes and with_boxes(boxes).footprint().distance(target) < gap:
            boxes.pop()
        return with_boxes(boxes)
    cx, cy, hl, ht, yaw = up.boxes[0]
    d = np.array([math.cos(yaw), math.sin(yaw)])
    wall_end = np.array([cx, cy]) - hl * d

    def box_of(length):
        mid = wall_end + 0.5 * length * d
        return (float(mid[0]), float(mid[1]), 0.5 * length, ht, yaw)

    lo, hi = 0.0, 2.0 * hl
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if with_boxes([box_of(mid)]).footprint().distance(target) >= gap:
            lo = mid
        else:
            hi = mid
    return with_boxes([box_of(lo)] if lo > 0 else [])


def scene_fences(scene: dict, loc1: Fence, loc2: Fence) -> list[FenceGeom]:
    """Built fences, upstream first (Location 2 then Location 1).

    The upstream fence is trimmed (:func:`trim_to_gap`) to keep ``fences.min_gap`` from the
    downstream one, so that two fences never form a closed V.
    """
    up, down = fence_geometry(scene, "loc2", loc2), fence_geometry(scene, "loc1", loc1)
    if up is not None and down is not None:
        up = trim_to_gap(up, down, float(scene["fences"]["min_gap"]))
        if not up.boxes:
            up = None
    return [f for f in (up, down) if f is not None]
