"""The simulated scene beyond its fences: the belt's contact with the part, and Table 1.

The fences' geometry is :mod:`feeder.lane.geometry`, the settings are read by
:func:`feeder.lane.settings.load_settings`.

``feeder scene-table --out results/tables/table1.csv [--settings JSON]`` writes Table 1 (every
physical parameter of the scene and of the simulation presets) from the config.
"""

from __future__ import annotations

import argparse

from feeder.errors import FeederError
from feeder.lane.settings import load_settings

# A part stands on its pads only when they surround its centre of mass: with 1 or 2 pads (on a line)
# it tipped over and sank through the belt, which its pieces do not touch (measured).
MIN_PADS = 3


# --------------------------------------------------------------------------------------------
# The belt's contact with the part (read by feeder.sim.body; rows of Table 1)
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


def footprint_setting(scene: dict) -> tuple[str, int, float]:
    """(model, pads, pad radius m) of ``scene.belt.footprint``; missing: the pieces (the paper's way)."""
    fp = scene["belt"].get("footprint") or {}
    model = fp.get("model", "pieces")
    if model == "pieces":
        return "pieces", 0, 0.0
    if model != "pads":
        raise FeederError(f"scene.belt.footprint.model: pieces or pads (got {model!r})")
    count, radius = fp.get("pads"), fp.get("pad_radius")
    if not isinstance(count, int) or count < MIN_PADS or radius is None or not float(radius) > 0:
        raise FeederError(
            f"scene.belt.footprint: pads (an integer >= {MIN_PADS}) and pad_radius (m, > 0) go with model: pads "
            f"(got {count!r} and {radius!r})"
        )
    return "pads", count, float(radius)


def wall_contact_setting(scene: dict) -> tuple[str, float, float]:
    """(model, slab depth m, largest turn of a slab's chain in degrees) of
    ``scene.part.wall_contact``: how the part meets walls and fences.

    ``pieces`` (missing: the paper's way): through its convex pieces, so the contact points follow
    the decomposition. ``outline``: through convex slabs along runs of its outline edges, reaching
    ``depth`` into the part (:func:`feeder.sim.body.outline_slabs`), which no decomposition enters;
    it needs the footprint pads (the slabs meet only walls and fences, the pads only the belt).
    """
    wc = scene["part"].get("wall_contact") or {}
    model = wc.get("model", "pieces")
    if model == "pieces":
        return "pieces", 0.0, 0.0
    if model != "outline":
        raise FeederError(f"scene.part.wall_contact.model: pieces or outline (got {model!r})")
    depth, turn = wc.get("depth"), wc.get("max_turn_deg")
    if isinstance(depth, bool) or not isinstance(depth, (int, float)) or not depth > 0:
        raise FeederError(f"scene.part.wall_contact.depth: a slab depth in m, > 0, for model outline (got {depth!r})")
    if isinstance(turn, bool) or not isinstance(turn, (int, float)) or not 0 <= turn < 180:
        raise FeederError(f"scene.part.wall_contact.max_turn_deg: degrees in [0, 180) for model outline (got {turn!r})")
    if footprint_setting(scene)[0] != "pads":
        raise FeederError(
            "scene.part.wall_contact: model outline goes with footprint pads (scene.belt.footprint.model: pads); "
            "the slabs alone would rest the part on its rim"
        )
    return "outline", float(depth), float(turn)


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


def wall_contact_row(scene: dict) -> tuple[str, str, str]:
    """Table 1 row of how the part meets walls and fences (``scene.part.wall_contact``)."""
    model, depth, turn = wall_contact_setting(scene)
    if model == "pieces":
        return ("Wall and fence contact", "convex pieces", "each convex piece of the part meets walls and fences")
    return (
        "Wall and fence contact",
        f"outline slabs, {depth:g} m deep, {turn:g} deg a slab",
        "convex slabs along runs of outline edges meet walls and fences, whatever the decomposition",
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
        wall_contact_row(scene),
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
            f"r = {cv['radius']:g}, span {cv['span_deg']:g} deg, {cv['segments']} "
            f"{'chords as one convex hull' if cv.get('build', 'boxes') == 'hull' else 'boxes'}, "
            f"slot {cv['slot'].upper()}",
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
