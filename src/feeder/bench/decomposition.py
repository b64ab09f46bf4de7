"""Is the belt friction a property of the part, or of how it was cut? (``feeder bench-decomposition``).

Issue #37, item 1. The same part is built under several valid convex decompositions (pure
functions below: the library's own pieces, a constrained triangulation, a fan from the centroid,
strips across the long axis, cuts through every reflex vertex along one edge or the other), each
substituted for ``geom.convex_pieces`` and simulated exactly as given (the part model's merge,
:func:`feeder.sim.body.merge_pieces`, is off: ``merge_tolerance: None``; at tolerance 0 it would
fuse back any pieces whose union is convex, e.g. a rectangle's two triangles). Each decomposition
runs under each contact model (``pieces``: each convex piece touches the belt; ``padsK``: K footprint pads of uniform
pressure, :func:`feeder.sim.body.footprint_pads`) with the same initial yaws (offset ``a``), one
drop per world (:func:`feeder.sim.drops.run_each`), so drop ``i`` of two runs is paired.

A model's **floor** comes from its own runs of the library decomposition: paired, the same drops
with every initial yaw ``nudge_deg`` later (same-basin fraction, median |Δ final yaw|); by the
label, the label of offset ``a`` against that of offset ``b``, a second seeded offset of the same
design (sup|ΔCDF|, circular W1). A comparison **passes** when every one of its four distances is
within ``floor_factor`` times the floor (the missed-basin share's floor is at least one drop in
``drops``: a floor measured on a few dozen drops is itself uncertain). No floor is below what
the label can show (:func:`label_resolution`): half a bin for median |Δyaw|, one drop's mass for
sup|ΔCDF|, one drop moved by one bin for circular W1. Without it a model whose drops repeat
exactly (pads against an aligning fence: a measured floor of 1e-6 degrees and 1e-16) fails on any
difference at all, however far below the label's bins; the measured floors stay in the table
(``own_floor_*``) beside the floors applied (``floor_*``). A model passes the
decomposition test when every decomposition pair of every part and configuration passes; the pad
counts are **converged** when two pad counts pass the same test against each other (each
decomposition, floor: the larger of the two models' floors).

This command simulates and writes the raw drops (``--out-raw``, one row per drop), which are kept;
``feeder bench-decomposition-table`` (:mod:`feeder.bench.decomposition_table`) makes the table
from them, so a new statistic needs no simulation.
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import math
import re
import sys
import time
from multiprocessing import get_context

import numpy as np
import pandas as pd

from feeder.errors import FeederError

PIECES = "pieces"
OUTLINE_SUFFIX = "+outline"  # a contact model's suffix: walls and fences meet the outline slabs
LIBRARY = "library"
_STRIPS = re.compile(r"^strips([2-9])$")
NAMED = ("library", "triangles", "fan", "cut_in", "cut_out", "greedy")  # and strips2 ... strips9
_AREA_RTOL = 1e-9  # relative area slack of the tiling check (float round-off of the cuts)


# ----------------------------------------------------------------------------------------------
# Decompositions (pure)
# ----------------------------------------------------------------------------------------------
def _polygon(outline, holes=()):
    from shapely.geometry import Polygon

    return Polygon(np.asarray(outline, np.float64), [np.asarray(h, np.float64) for h in holes])


def _convex_parts(poly) -> list[np.ndarray]:
    """A shapely polygon (possibly with holes) as convex pieces: itself when convex, else the
    library's exact decomposition of it (:func:`feeder.parts.geometry.convex_decomposition`)."""
    from shapely.geometry.polygon import orient

    from feeder.parts.geometry import clean_outline, convex_decomposition, is_convex

    poly = orient(poly, 1.0)
    outline = clean_outline(np.asarray(poly.exterior.coords)[:-1], rel_tol=1e-12)
    holes = [clean_outline(np.asarray(r.coords)[:-1], rel_tol=1e-12) for r in poly.interiors]
    if not holes and is_convex(outline):
        return [outline]
    return [np.asarray(p, np.float64) for p in convex_decomposition(outline, holes)]


def _explode(geometry) -> list:
    """The polygons (of positive area) of a shapely geometry."""
    if geometry.is_empty:
        return []
    if geometry.geom_type == "Polygon":
        return [geometry] if geometry.area > 0 else []
    return [g for part in getattr(geometry, "geoms", []) for g in _explode(part)]


def cut_by_lines(outline, lines, holes=()) -> list[np.ndarray]:
    """The region (outline less holes) cut along full lines ``(point, direction)``, then each cell
    made convex (:func:`_convex_parts`). The cells tile the region exactly."""
    poly = _polygon(outline, holes)
    x0, y0, x1, y1 = poly.bounds
    reach = 4.0 * math.hypot(x1 - x0, y1 - y0)
    cells = [poly]
    for point, direction in lines:
        p, d = np.asarray(point, np.float64), np.asarray(direction, np.float64)
        d = d / np.linalg.norm(d)
        n = np.array([-d[1], d[0]])
        a, b = p - reach * d, p + reach * d
        left = _polygon([a, b, b + reach * n, a + reach * n])
        right = _polygon([a, a - reach * n, b - reach * n, b])
        cells = [g for c in cells for half in (left, right) for g in _explode(c.intersection(half))]
    return [piece for c in cells for piece in _convex_parts(c)]


def long_axis(outline, holes=()) -> float:
    """Angle (rad) of the region's principal long axis (largest ∫x'² about the centroid)."""
    from feeder.parts.geometry import profile_moments

    _, _, (sy, sx, sxy) = profile_moments(np.asarray(outline, np.float64), [np.asarray(h) for h in holes])
    return 0.5 * math.atan2(2.0 * sxy, sx - sy)


def strips(outline, count: int, holes=()) -> list[np.ndarray]:
    """``count`` strips of equal width across the long axis (cut perpendicular to it), each made
    convex: a rectangle in ``count`` rectangles."""
    count = int(count)
    if count < 1:
        raise FeederError(f"strips: need at least one strip (got {count})")
    angle = long_axis(outline, holes)
    axis = np.array([math.cos(angle), math.sin(angle)])
    along = np.asarray(outline, np.float64) @ axis
    lo, hi = float(along.min()), float(along.max())
    normal = np.array([-axis[1], axis[0]])
    cuts = [(axis * (lo + (hi - lo) * k / count), normal) for k in range(1, count)]
    return cut_by_lines(outline, cuts, holes)


def triangles(outline, holes=()) -> list[np.ndarray]:
    """The constrained Delaunay triangles of the region (:func:`feeder.parts.geometry.triangulate`)."""
    from feeder.parts.geometry import profile_vertices, triangulate

    verts = profile_vertices(np.asarray(outline, np.float64), holes)
    return [verts[list(t)] for t in triangulate(np.asarray(outline, np.float64), holes)]


def fan(outline) -> list[np.ndarray]:
    """Triangles from the area centroid to every edge of a convex outline (a rectangle in four)."""
    from feeder.parts.geometry import is_convex, polygon_moments

    outline = np.asarray(outline, np.float64)
    if not is_convex(outline):
        raise FeederError("fan: the outline is not convex (its centroid need not see every edge)")
    _, c, _ = polygon_moments(outline)
    return [np.array([c, outline[i], outline[(i + 1) % len(outline)]]) for i in range(len(outline))]


def reflex_cuts(outline, edge: str, holes=()) -> list[np.ndarray]:
    """Cut along a full line through every reflex vertex of the CCW outline, in the direction of
    its incoming edge (``edge="in"``) or its outgoing one (``"out"``), then make each cell convex:
    an L in two rectangles one way or the other."""
    if edge not in ("in", "out"):
        raise FeederError(f"reflex cuts: edge is 'in' or 'out' (got {edge!r})")
    pts = np.asarray(outline, np.float64)
    lines = []
    for i in range(len(pts)):
        prev, here, nxt = pts[i - 1], pts[i], pts[(i + 1) % len(pts)]
        e_in, e_out = here - prev, nxt - here
        if e_in[0] * e_out[1] - e_in[1] * e_out[0] < 0:  # turns clockwise: reflex
            lines.append((here, e_in if edge == "in" else e_out))
    if not lines:
        raise FeederError("reflex cuts: the outline has no reflex vertex")
    return cut_by_lines(pts, lines, holes)


def greedy(outline, holes=()) -> list[np.ndarray]:
    """The triangles merged pair by pair in list order while the union stays convex
    (:func:`feeder.sim.body.merge_pieces` at tolerance 0): Hertel–Mehlhorn in another order."""
    from feeder.sim.body import merge_pieces

    return [np.asarray(p, np.float64) for p in merge_pieces(triangles(outline, holes), 0.0)]


def decompose(geom, name: str, merge_tolerance: float) -> list[np.ndarray]:
    """The pieces of decomposition ``name`` of a :class:`~feeder.parts.geometry.PartGeometry`:
    ``library`` (the study's own: the library pieces merged at the preset's ``merge_tolerance``,
    what every simulation uses), ``triangles``, ``fan``, ``stripsK``, ``cut_in``, ``cut_out``,
    ``greedy``. Checked by :func:`check_decomposition`."""
    from feeder.sim.body import merge_pieces

    outline, holes = np.asarray(geom.outline, np.float64), list(geom.holes)
    strip = _STRIPS.match(name)
    if name == LIBRARY:
        pieces = merge_pieces(geom.convex_pieces, float(merge_tolerance))
    elif name == "triangles":
        pieces = triangles(outline, holes)
    elif name == "fan":
        if holes:
            raise FeederError(f"part {geom.part_id}: fan needs a part without holes")
        pieces = fan(outline)
    elif name in ("cut_in", "cut_out"):
        pieces = reflex_cuts(outline, name[4:], holes)
    elif name == "greedy":
        pieces = greedy(outline, holes)
    elif strip:
        pieces = strips(outline, int(strip.group(1)), holes)
    else:
        raise FeederError(f"decomposition {name!r}: one of {', '.join(NAMED)} or strips2 ... strips9")
    pieces = [np.asarray(p, np.float64) for p in pieces]
    check_decomposition(outline, pieces, holes, what=f"part {geom.part_id}, {name}")
    return pieces


def check_decomposition(outline, pieces, holes=(), what: str = "decomposition") -> None:
    """FeederError unless ``pieces`` are convex polygons that tile the region: each convex and of
    positive area, their areas summing to the region's (no overlap) and their union equal to it."""
    from shapely.ops import unary_union

    from feeder.parts.geometry import clean_outline, is_convex

    region = _polygon(outline, holes)
    polys = []
    for k, p in enumerate(pieces):
        poly = _polygon(p)
        if not poly.is_valid or poly.area <= 0 or not is_convex(clean_outline(p, rel_tol=1e-12)):
            raise FeederError(f"{what}: piece {k} is not a convex polygon with an area")
        polys.append(poly)
    total, union = sum(p.area for p in polys), unary_union(polys)
    slack = _AREA_RTOL * region.area
    if abs(total - region.area) > slack or union.symmetric_difference(region).area > slack:
        raise FeederError(
            f"{what}: the pieces do not tile the part (areas {total:.6g} summed, union off by "
            f"{union.symmetric_difference(region).area:.3g}, part {region.area:.6g})"
        )


def with_pieces(geom, pieces):
    """The part with ``pieces`` for its convex pieces (nothing else changes)."""
    return dataclasses.replace(geom, convex_pieces=[np.asarray(p, np.float64) for p in pieces])


# ----------------------------------------------------------------------------------------------
# Runs (simulation)
# ----------------------------------------------------------------------------------------------
def model_scene(scene: dict, model: str) -> dict:
    """The scene under contact model ``pieces`` or ``padsK`` (the belt footprint,
    :func:`feeder.bench.contact.footprint_scene`), with ``+outline`` the part meeting walls and fences
    through its outline slabs (``scene.part.wall_contact``, depth as configured) instead of its pieces."""
    from feeder.bench.contact import footprint_scene

    footprint, plus, wall = model.partition(OUTLINE_SUFFIX)
    if (footprint != PIECES and not re.fullmatch(r"pads[1-9][0-9]*", footprint)) or wall:
        raise FeederError(f"contact model {model!r}: pieces or padsK (K pads), optionally followed by {OUTLINE_SUFFIX}")
    out = footprint_scene(scene, footprint, float(scene["belt"]["footprint"]["pad_radius"]))
    wall = scene["part"]["wall_contact"]
    out["part"]["wall_contact"] = dict(wall, model="outline" if plus else "pieces")
    return out


def run_decomposition(geom, pieces, config: str, yaws, scene: dict, preset: dict) -> dict:
    """The drops of one decomposition, one drop per world, pieces as given: final yaws, statuses,
    process CPU seconds."""
    from feeder.lane.fences import parse_location
    from feeder.sim.drops import run_each

    part = with_pieces(geom, pieces)
    loc1, loc2 = config.split("|")
    as_given = dict(preset, merge_tolerance=None)  # the part model merges nothing back
    start = time.process_time()
    out = run_each(part, parse_location(loc1), parse_location(loc2), np.asarray(yaws, np.float64), scene, as_given)
    cpu = time.process_time() - start
    return {"final_yaw_deg": out["final_yaw_deg"], "status": out["status"].astype(str), "cpu_s": cpu}


def plan_runs(bench: dict, base_seed: int) -> list[dict]:
    """Every run of the bench: per part, configuration and model, each decomposition at offset
    ``a``, and the library decomposition nudged by ``nudge_deg`` and at offset ``b``."""
    from feeder.sim.drops import drop_seed, initial_yaws

    drops, sampling, nudge = int(bench["drops"]), str(bench["sampling"]), float(bench["nudge_deg"])
    runs = []
    for part, names in bench["parts"].items():
        names = [LIBRARY] + [n for n in names if n != LIBRARY]
        for config in bench["configurations"]:
            yaws = {
                tag: initial_yaws(drop_seed(part, config, base_seed + offset), drops, sampling)
                for tag, offset in (("a", 0), ("b", int(bench["offset_b_seed"])))
            }
            for model in bench["models"]:
                plan = [(n, "a", 0.0) for n in names] + [(LIBRARY, "a", nudge), (LIBRARY, "b", 0.0)]
                runs += [
                    {
                        "part": part,
                        "configuration": config,
                        "model": model,
                        "decomposition": name,
                        "offset": tag,
                        "yaw_shift_deg": shift,
                        "yaws": yaws[tag] + shift,
                    }
                    for name, tag, shift in plan
                ]
    return runs


def _job(job):
    run, parts_dir, scene, preset = job
    from feeder.parts.geometry import load_part

    geom = load_part(f"{parts_dir}/{run['part']}.stl")
    pieces = decompose(geom, run["decomposition"], float(preset["merge_tolerance"]))
    out = run_decomposition(geom, pieces, run["configuration"], run["yaws"], model_scene(scene, run["model"]), preset)
    return run, len(pieces), out


# ----------------------------------------------------------------------------------------------
# Command
# ----------------------------------------------------------------------------------------------
def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder bench-decomposition", description=__doc__.splitlines()[0])
    parser.add_argument("--settings", required=True, help="JSON {scene, sim, parts} config sections")
    parser.add_argument(
        "--out-raw", required=True, help="every drop (CSV): initial and final yaw, status, CPU of its run"
    )
    args = parser.parse_args(argv)
    from feeder.config import parse_settings

    cfg = parse_settings(args.settings, "scene", "sim", "parts")
    from feeder.io import write_csv
    from feeder.sim.drops import get_preset

    try:
        scene, sim_cfg, parts_dir = cfg["scene"], cfg["sim"], cfg["parts"]["dir"]
        bench, base_seed = sim_cfg["decomposition_bench"], int(sim_cfg["base_seed"])
        preset = get_preset(sim_cfg["presets"], bench["preset"])
        workers = max(1, int(bench["workers"]))
        for model in bench["models"]:
            model_scene(scene, model)
    except (KeyError, TypeError, ValueError) as err:
        raise FeederError(f"--settings lacks or mistypes {err}") from None
    raw = simulate_all(bench, base_seed, parts_dir, scene, preset, workers)
    write_csv(args.out_raw, raw)
    print(f"feeder bench-decomposition: {len(raw)} drops, {args.out_raw}", file=sys.stderr)
    return 0


def simulate_all(bench, base_seed, parts_dir, scene, preset, workers) -> pd.DataFrame:
    """Every run of :func:`plan_runs` (dearest first, ``workers`` processes): the raw drops."""
    from feeder.parts.geometry import load_part

    runs = plan_runs(bench, base_seed)
    for part, names in bench["parts"].items():  # every decomposition is valid before anything runs
        geom = load_part(f"{parts_dir}/{part}.stl")
        for name in [LIBRARY, *names]:
            decompose(geom, name, float(preset["merge_tolerance"]))
    jobs = [(run, parts_dir, copy.deepcopy(scene), preset) for run in runs]
    jobs.sort(key=lambda j: (j[0]["model"] != PIECES, j[0]["decomposition"] == LIBRARY))
    bar = None
    if sys.stderr.isatty():
        from tqdm import tqdm

        bar = tqdm(total=len(jobs), unit="run", file=sys.stderr)
    records = []
    with get_context("fork").Pool(workers) as pool:
        for run, count, out in pool.imap_unordered(_job, jobs):
            keys = {k: v for k, v in run.items() if k != "yaws"}
            records += [
                keys
                | {
                    "pieces": count,
                    "drop": i,
                    "initial_yaw_deg": float(y0),
                    "final_yaw_deg": float(y),
                    "status": s,
                    "cpu_s": out["cpu_s"],
                }
                for i, (y0, y, s) in enumerate(zip(run["yaws"], out["final_yaw_deg"], out["status"]))
            ]
            if bar is not None:
                bar.update(1)
    if bar is not None:
        bar.close()
    keys = ["part", "configuration", "model", "decomposition", "offset", "yaw_shift_deg", "drop"]
    return pd.DataFrame(records).sort_values(keys, ignore_index=True)
