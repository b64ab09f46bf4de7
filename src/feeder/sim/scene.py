"""The simulated scene: its parameters (the ``scene`` config section), fence geometry, Table 1.

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

``feeder scene-table --out results/tables/table1.csv [--settings JSON]`` writes Table 1 (every
physical parameter of the scene and of the simulation presets) from the config.
"""

from __future__ import annotations

import argparse
import math
import os
from dataclasses import dataclass

import numpy as np

from feeder.errors import FeederError
from feeder.sim.fences import Fence


# --------------------------------------------------------------------------------------------
# Settings
# --------------------------------------------------------------------------------------------
def load_settings(settings_json: str | None = None, root: str | os.PathLike | None = None):
    """``(scene, presets)`` from a ``--settings`` JSON string or else from the study config.

    The JSON holds ``{"scene": {...}, "presets": {...}}`` (or ``{"scene": ..., "sim": {"presets":
    ...}}``: the config sections as they are). Without it, ``config/config.yaml`` of the study in
    ``root`` is read by :func:`feeder.config.load_study_config`; ``root`` defaults to
    :func:`feeder.config.study_root` (the working directory when it holds that file, else the
    repository).
    """
    if settings_json is not None:
        from feeder.config import parse_settings

        data = parse_settings(settings_json)
    else:
        from feeder.config import load_study_config, study_root

        data = load_study_config(root=study_root() if root is None else root)
    presets = data.get("presets")
    if presets is None:
        presets = (data.get("sim") or {}).get("presets")
    scene = data.get("scene")
    if not isinstance(scene, dict):
        raise FeederError("settings lack the 'scene' section")
    if not isinstance(presets, dict) or not presets:
        raise FeederError("settings lack the simulation presets ('presets' or 'sim.presets')")
    return scene, presets


# --------------------------------------------------------------------------------------------
# Fence geometry (pure functions)
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FenceGeom:
    """One built fence: boxes ``(cx, cy, half_length, half_thickness, yaw_rad)`` in lane coords."""

    location: str
    fence: Fence
    side: int  # +1 right (x > 0), -1 left
    boxes: tuple[tuple[float, float, float, float, float], ...]

    def footprint(self):
        """Union of the boxes' footprints (shapely)."""
        from shapely.geometry import Polygon
        from shapely.ops import unary_union

        return unary_union([Polygon(box_corners(*b)) for b in self.boxes])

    @property
    def length(self) -> float:
        return float(sum(2.0 * b[2] for b in self.boxes))


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
        cc = fc["curved"]
        slot_x = float(fc["slots"][cc["slot"]])
        # the arc (radius r) is the fence's centre line; its outer face lies at r + thickness / 2
        pts, centre = curved_polyline(
            fence.angle, side, slot_x, y0, float(cc["radius"]), float(cc["span_deg"]), int(cc["segments"]), offset=ht
        )
        boxes = arc_boxes(pts, centre, ht)
    return FenceGeom(location, fence, side, boxes)


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
        return FenceGeom(up.location, up.fence, up.side, tuple(boxes))

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


# --------------------------------------------------------------------------------------------
# Table 1
# --------------------------------------------------------------------------------------------
def belt_contact(belt: dict) -> tuple[float, float] | None:
    """(stiffness N/m, damping N s/m) per contact point of a compliant belt, or None for a rigid one."""
    k, d = belt.get("contact_stiffness"), belt.get("contact_damping")
    if k is None and d is None:
        return None
    if k is None or d is None or float(k) <= 0 or float(d) < 0:
        raise FeederError(
            "scene.belt: contact_stiffness (> 0) and contact_damping (>= 0) go together; "
            f"both null = rigid contact (got {k!r} and {d!r})"
        )
    return float(k), float(d)


def belt_contact_row(belt: dict) -> tuple[str, str, str]:
    """Table 1 row of the belt-part contact model: rigid, or a spring-damper per contact point."""
    contact = belt_contact(belt)
    if contact is None:
        return (
            "Belt contact",
            "rigid",
            "hard constraint; how a flat part's weight splits over its contact points is left to the solver",
        )
    k, d = contact
    return (
        "Belt contact stiffness / damping",
        f"{k:g} / {d:g}",
        "N/m and N s/m per contact point (Bullet contactStiffness/contactDamping): a compliant belt, "
        "so a flat part's weight splits over its contact points by their penetration",
    )


def belt_footprint_row(scene: dict) -> tuple[str, str, str]:
    """Table 1 row of how the part's weight rests on the belt (``scene.belt.footprint``)."""
    from feeder.sim.body import footprint_setting

    model, count, radius = footprint_setting(scene)
    if model == "pieces":
        return (
            "Belt footprint",
            "convex pieces",
            "each convex piece of the part touches the belt (up to 4 contact points a piece)",
        )
    return (
        "Belt footprint",
        f"{count} pads, {radius:g} m",
        "spheres at the centroids of equal-area cells of the footprint carry the weight (uniform pressure); "
        "the exact pieces meet only walls and fences",
    )


def table1_rows(scene: dict, presets: dict) -> list[tuple[str, str, str]]:
    """(parameter, value, units / notes) for every physical parameter of the scene and presets."""
    b, w, pt, fc = scene["belt"], scene["walls"], scene["part"], scene["fences"]
    st, cv = fc["straight"], fc["curved"]
    slots = fc["slots"]
    rows = [
        ("Simulator", "pybullet (Bullet 3) DIRECT", "one client per process, multibody rigid bodies"),
        ("Gravity", f"{scene['gravity']:g}", "m/s^2, along -z"),
        (
            "Conveyor speed",
            f"{b['speed']:g}",
            "m/s along +y; fixed-base belt slab per lane given this velocity when a drop starts",
        ),
        (
            "Friction combination",
            "product",
            f"Bullet multiplies the two bodies' coefficients: part-belt {pt['friction'] * b['friction']:g}, "
            f"part-fence {pt['friction'] * fc['friction']:g}, part-wall {pt['friction'] * w['friction']:g}",
        ),
        ("Belt friction (Coulomb mu)", f"{b['friction']:g}", "static = kinetic"),
        ("Part friction (Coulomb mu)", f"{pt['friction']:g}", "static = kinetic"),
        ("Fence friction (Coulomb mu)", f"{fc['friction']:g}", "static = kinetic"),
        ("Wall friction (Coulomb mu)", f"{w['friction']:g}", "containment walls"),
        ("Restitution", f"{scene['restitution']:g}", "every body"),
        ("Cone friction", "on", "enableConeFriction (pyramid friction jams parts)"),
        ("Belt width", f"{2 * b['half_width']:g}", "m between the containment walls' inner faces"),
        ("Belt slab thickness", f"{b['thickness']:g}", "m; belt surface at z = 0"),
        belt_contact_row(b),
        belt_footprint_row(scene),
        ("Containment walls", f"{w['height']:g} x {w['thickness']:g}", "m, height x thickness"),
        ("Part density", f"{pt['density']:g}", "kg/m^3; mass, centre of mass and inertia from the exact polygon"),
        (
            "Part collision margin",
            f"{pt['collision_margin']:g}",
            "m; convex pieces are inset by it so the part keeps its true size",
        ),
        (
            "Initial part pose",
            f"x = 0, y = {b['start_y']:g}, flat, yaw ~ U[0, 360)",
            "m; placed on the belt already moving with it",
        ),
        (
            "Record point (full path)",
            f"y >= max({b['end_y']:g}, last fence end + {b['end_margin']:g})",
            "m; then at rest",
        ),
        (
            "Fence locations",
            f"Location 1 y = {fc['locations']['loc1']['y']:g} (right); "
            f"Location 2 y = {fc['locations']['loc2']['y']:g} (left)",
            "m" + ("; sides mirrored" if scene.get("mirror") else ""),
        ),
        ("Fence slots (A / B)", f"x = +-{slots['a']:g} / +-{slots['b']:g}", "m"),
        (
            "Fence cross-section",
            f"{fc['thickness']:g} x {fc['height']:g}",
            f"m, thickness x height; bottom {fc['clearance']:g} m above the belt",
        ),
        (
            "Straight fence",
            f"slot {st['slot'].upper()}, tip {st['tip_past_centre']:g} past the centre line, "
            f"length <= {st['max_length']:g}",
            "m; cuboid from the wall at angle theta to the travel direction, 0 < theta < 90",
        ),
        (
            "Curved fence",
            f"r = {cv['radius']:g}, span {cv['span_deg']:g} deg, {cv['segments']} boxes, slot {cv['slot'].upper()}",
            "arc centre x = x0 - r sin(theta), y = y0 + r cos(theta); 0 <= theta <= 90",
        ),
        (
            "Least gap between the fences",
            f"{fc['min_gap']:g}",
            "m; the upstream fence's tip is cut back to keep it (crossing fences trap parts)",
        ),
        (
            "Jam",
            f"travel < {scene['status']['jam_travel']:g} m in {scene['status']['jam_window_s']:g} s",
            "drop status 'jammed'",
        ),
        (
            "At rest",
            f"|v - v_belt| < {scene['status']['rest_speed']:g} m/s and "
            f"|w_z| < {scene['status']['rest_omega_deg_s']:g} deg/s for {scene['status']['rest_window_s']:g} s",
            "velocities from the displacement between state checks; "
            "final yaw recorded once at rest past the last fence",
        ),
        (
            "Flipped / fell off",
            f"tilt > {scene['status']['flip_tilt_deg']:g} deg / z < {scene['status']['fall_z']:g} m",
            "drop status",
        ),
        (
            "Time limit",
            f"{scene['status']['timeout_factor']:g} x path / speed + {scene['status']['timeout_extra_s']:g} s",
            "drop status 'timed_out'",
        ),
    ]
    for name, p in presets.items():
        rows.append(
            (
                f"Preset '{name}'",
                f"step {p['time_step'] * 1e3:g} ms, {p['substeps']} substeps, "
                f"{p['solver_iterations']} solver iterations",
                f"{p['lanes']} lanes per world; "
                + ("full belt path" if p["full_path"] else "only the fence region is stepped")
                + ("; steady slides along straight fences skipped" if p.get("skip_slides") else "")
                + (
                    f"; convex pieces merged within {p['merge_tolerance'] * 1e3:g} mm"
                    if p.get("merge_tolerance")
                    else ""
                ),
            )
        )
    return rows


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder scene-table", description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True, help="CSV to write (Table 1)")
    parser.add_argument(
        "--settings",
        default=None,
        help="JSON {scene, presets}; default config/config.yaml (of the working directory, else of the repository)",
    )
    args = parser.parse_args(argv)
    import pandas as pd

    from feeder.io import write_csv

    scene, presets = load_settings(args.settings)
    try:
        rows = table1_rows(scene, presets)
    except KeyError as err:
        raise FeederError(f"scene settings lack key {err}") from None
    write_csv(args.out, pd.DataFrame(rows, columns=["parameter", "value", "units_notes"]))
    return 0
