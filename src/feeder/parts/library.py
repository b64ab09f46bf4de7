"""The part library: shape families, the deterministic generator and part listing.

``parts/library.yaml`` declares every part (id, family, thickness, family parameters in mm) and
the point-cloud export settings; ``feeder parts generate`` turns it into ``parts/<id>.stl``
(binary, metres, extruded along z from 0 to the thickness), ``parts/<id>.xyz`` (the planar top
face as a CAD point-cloud export: ``x y z`` in mm, z = thickness) and ``parts/catalog.csv``.
Running it twice gives byte-identical files. Outline frames: each outline's bounding box has its
lower-left corner at the origin (like a CAD sketch), so the centroid is *not* at the origin.

Subcommands::

    feeder parts generate [--spec parts/library.yaml] [--out parts]
    feeder parts xyz PART.stl --out PART.xyz [--points N]   # face cloud of a user's STL
    feeder parts list [--dir parts] [--include ID ...]
    feeder parts fig6-data PATH... --out results/figdata/fig6_dft_reconstruction.npz
    feeder parts s1 PATH... --table results/tables/s1_dft_mse.csv --max-coefficients 50

``fig6-data`` and ``s1`` write the numbers of Fig. 6 (panel b) and Supplementary Fig. S1; the
figures are drawn from them by ``feeder figure fig6_dft_reconstruction`` / ``feeder figure
s1_dft_mse`` (:mod:`feeder.figures`).
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import math
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from feeder.errors import FeederError

ID_RE = re.compile(r"^[A-Za-z0-9-]+$")
LIBRARY_ID_RE = re.compile(r"^[a-z0-9]+(-[a-z0-9]+)*$")

CATALOG_COLUMNS = [
    "id",
    "family",
    "params",
    "thickness",
    "size",
    "n_points",
    "n_vertices",
    "area",
    "perimeter",
    "aspect_ratio",
    "convexity",
    "compactness",
    "eigen_ratio",
]


# --------------------------------------------------------------------------------------------
# Listing (called at Snakemake parse time: keep it cheap)
# --------------------------------------------------------------------------------------------
def list_parts(parts_dir: str | Path, include: str | list[str] = "all", exclude=()) -> list[str]:
    """Sorted ids of the ``<id>.stl`` files in ``parts_dir`` (optionally only ``include``), less
    those matching a shell pattern of ``exclude`` (``parts.exclude``)."""
    parts_dir = Path(parts_dir)
    if not parts_dir.is_dir():
        raise FeederError(f"parts directory {parts_dir} does not exist")
    ids = []
    for path in parts_dir.iterdir():
        if path.suffix.lower() != ".stl" or not path.is_file():
            continue
        if not ID_RE.match(path.stem):
            raise FeederError(
                f"{path}: part file names must be letters, digits and '-' only (no '_', which separates fence tokens)"
            )
        ids.append(path.stem)
    ids.sort()
    if include != "all":
        if isinstance(include, str):
            include = [include]
        missing = [i for i in include if i not in ids]
        if missing:
            raise FeederError(f"parts.include names part(s) with no STL in {parts_dir}: {', '.join(missing)}")
        ids = sorted(set(include))
    patterns = [str(p) for p in exclude or ()]
    return [i for i in ids if not any(fnmatch.fnmatchcase(i, pat) for pat in patterns)]


# --------------------------------------------------------------------------------------------
# Shape families: pure functions of their parameters (mm) -> outline (N, 2), CCW
# --------------------------------------------------------------------------------------------
def _arc(cx: float, cy: float, r: float, a0: float, a1: float, seg_full: int) -> np.ndarray:
    """Points on a circular arc from angle a0 to a1 (radians, either direction), both ends."""
    m = max(2, int(math.ceil(seg_full * abs(a1 - a0) / (2 * math.pi))))
    t = np.linspace(a0, a1, m + 1)
    return np.column_stack([cx + r * np.cos(t), cy + r * np.sin(t)])


def _ngon(p: dict, seg: int) -> np.ndarray:
    n, r = int(p["n"]), float(p["radius"])
    t = np.pi / 2 + 2 * np.pi * np.arange(n) / n
    pts = np.column_stack([r * np.cos(t), r * np.sin(t)])
    pts[:, 0] *= float(p.get("stretch", 1.0))
    return pts


def _triangle(p: dict, seg: int) -> np.ndarray:
    b, h, ax = float(p["base"]), float(p["height"]), float(p["apex_x"])
    return np.array([[0.0, 0.0], [b, 0.0], [ax, h]])


def _rect(p: dict, seg: int) -> np.ndarray:
    w, h = float(p["width"]), float(p["height"])
    return np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]])


def _rrect(p: dict, seg: int) -> np.ndarray:
    w, h, r = float(p["width"]), float(p["height"]), float(p["radius"])
    if not 0 < r <= min(w, h) / 2:
        raise FeederError(f"rrect radius {r} must be in (0, min(width, height)/2]")
    corners = [(w - r, r, -np.pi / 2), (w - r, h - r, 0.0), (r, h - r, np.pi / 2), (r, r, np.pi)]
    pts = [_arc(cx, cy, r, a, a + np.pi / 2, seg) for cx, cy, a in corners]
    out = np.concatenate(pts)
    # drop the duplicated joint where two arcs meet a zero-length straight (r = w/2 or h/2)
    keep = np.linalg.norm(out - np.roll(out, 1, axis=0), axis=1) > 1e-9
    return out[keep]


def _ellipse(p: dict, seg: int) -> np.ndarray:
    a, b = float(p["a"]), float(p["b"])
    t = 2 * np.pi * np.arange(seg) / seg
    return np.column_stack([a * np.cos(t), b * np.sin(t)])


def _ibeam(p: dict, seg: int) -> np.ndarray:
    w, h, f, web = float(p["width"]), float(p["height"]), float(p["flange"]), float(p["web"])
    if not (2 * f < h and web < w):
        raise FeederError("ibeam needs 2*flange < height and web < width")
    x0, x1 = (w - web) / 2, (w + web) / 2
    return np.array(
        [
            [0, 0],
            [w, 0],
            [w, f],
            [x1, f],
            [x1, h - f],
            [w, h - f],
            [w, h],
            [0, h],
            [0, h - f],
            [x0, h - f],
            [x0, f],
            [0, f],
        ],
        dtype=float,
    )


def _lshape(p: dict, seg: int) -> np.ndarray:
    w, h, tx, ty = float(p["width"]), float(p["height"]), float(p["leg_x"]), float(p["leg_y"])
    if not (tx < h and ty < w):
        raise FeederError("lshape needs leg_x < height and leg_y < width")
    return np.array([[0, 0], [w, 0], [w, tx], [ty, tx], [ty, h], [0, h]], dtype=float)


def _tshape(p: dict, seg: int) -> np.ndarray:
    w, h, f, s = float(p["width"]), float(p["height"]), float(p["flange"]), float(p["stem"])
    if not (f < h and s < w):
        raise FeederError("tshape needs flange < height and stem < width")
    x0, x1 = (w - s) / 2, (w + s) / 2
    return np.array([[x0, 0], [x1, 0], [x1, h - f], [w, h - f], [w, h], [0, h], [0, h - f], [x0, h - f]], dtype=float)


def _ushape(p: dict, seg: int) -> np.ndarray:
    w, h, wall, base = float(p["width"]), float(p["height"]), float(p["wall"]), float(p["base"])
    if not (2 * wall < w and base < h):
        raise FeederError("ushape needs 2*wall < width and base < height")
    return np.array(
        [[0, 0], [w, 0], [w, h], [w - wall, h], [w - wall, base], [wall, base], [wall, h], [0, h]], dtype=float
    )


def _cross(p: dict, seg: int) -> np.ndarray:
    w, h, arm = float(p["width"]), float(p["height"]), float(p["arm"])
    if not (arm < w and arm < h):
        raise FeederError("cross needs arm < width and arm < height")
    x0, x1, y0, y1 = (w - arm) / 2, (w + arm) / 2, (h - arm) / 2, (h + arm) / 2
    return np.array(
        [
            [x0, 0],
            [x1, 0],
            [x1, y0],
            [w, y0],
            [w, y1],
            [x1, y1],
            [x1, h],
            [x0, h],
            [x0, y1],
            [0, y1],
            [0, y0],
            [x0, y0],
        ],
        dtype=float,
    )


def _zshape(p: dict, seg: int) -> np.ndarray:
    """A Z section: a web of thickness ``web`` up the middle, a bottom flange to the left and a top
    flange to the right, each ``flange`` thick."""
    w, h, f, t = float(p["width"]), float(p["height"]), float(p["flange"]), float(p["web"])
    if not (2 * f < h and t < w):
        raise FeederError("zshape needs 2*flange < height and web < width")
    x0, x1 = (w - t) / 2, (w + t) / 2
    return np.array([[0, 0], [x1, 0], [x1, h - f], [w, h - f], [w, h], [x0, h], [x0, f], [0, f]], dtype=float)


def _hat(p: dict, seg: int) -> np.ndarray:
    """A hat (omega) section: walls ``wall`` thick, a brim of width ``brim`` on each side."""
    w, h, t, b = float(p["width"]), float(p["height"]), float(p["wall"]), float(p["brim"])
    if not (2 * (b + t) < w and t < h):
        raise FeederError("hat needs 2*(brim + wall) < width and wall < height")
    return np.array(
        [
            [0, 0],
            [b + t, 0],
            [b + t, h - t],
            [w - b - t, h - t],
            [w - b - t, 0],
            [w, 0],
            [w, t],
            [w - b, t],
            [w - b, h],
            [b, h],
            [b, t],
            [0, t],
        ],
        dtype=float,
    )


def _crescent(p: dict, seg: int) -> np.ndarray:
    """Disc of ``radius`` minus a disc of ``inner_radius`` whose centre is ``offset`` to +x."""
    big, r, d = float(p["radius"]), float(p["inner_radius"]), float(p["offset"])
    if not (big - r < d < big + r and r < big):
        raise FeederError("crescent needs radius - inner_radius < offset < radius + inner_radius")
    xi = (d * d + big * big - r * r) / (2 * d)
    yi = math.sqrt(big * big - xi * xi)
    t_out = math.atan2(yi, xi)
    outer = _arc(0.0, 0.0, big, t_out, 2 * math.pi - t_out, seg)  # CCW, far side
    s0 = math.atan2(-yi, xi - d)
    s1 = math.atan2(yi, xi - d) - 2 * math.pi
    inner = _arc(d, 0.0, r, s0, s1, seg)  # CW along the bite
    return np.concatenate([outer, inner[1:-1]])


def _star(p: dict, seg: int) -> np.ndarray:
    n, ro, ri = int(p["points"]), float(p["outer"]), float(p["inner"])
    t = np.pi / 2 + np.pi * np.arange(2 * n) / n
    r = np.where(np.arange(2 * n) % 2 == 0, ro, ri)
    return np.column_stack([r * np.cos(t), r * np.sin(t)])


def _gear(p: dict, seg: int) -> np.ndarray:
    n, rr, rt = int(p["teeth"]), float(p["root"]), float(p["tip"])
    fr, ft = float(p["root_frac"]), float(p["tip_frac"])
    if not (0 < ft <= fr < 1 and rt > rr):
        raise FeederError("gear needs 0 < tip_frac <= root_frac < 1 and tip > root")
    pitch = 2 * np.pi / n
    pts = []
    for i in range(n):
        c = np.pi / 2 + i * pitch
        for ang, rad in [
            (c - fr * pitch / 2, rr),
            (c - ft * pitch / 2, rt),
            (c + ft * pitch / 2, rt),
            (c + fr * pitch / 2, rr),
        ]:
            pts.append([rad * np.cos(ang), rad * np.sin(ang)])
    return np.asarray(pts)


def _keyhole(p: dict, seg: int) -> np.ndarray:
    """Circle of ``radius`` at the origin with a slot of ``slot_width`` reaching down to
    ``-slot_length`` (measured from the circle's centre)."""
    r, w, length = float(p["radius"]), float(p["slot_width"]), float(p["slot_length"])
    if not (w < 2 * r and length > r):
        raise FeederError("keyhole needs slot_width < 2*radius and slot_length > radius")
    yc = math.sqrt(r * r - (w / 2) ** 2)
    a0 = math.atan2(-yc, w / 2)
    a1 = math.atan2(-yc, -w / 2) + 2 * math.pi
    arc = _arc(0.0, 0.0, r, a0, a1, seg)
    return np.concatenate([arc, [[-w / 2, -length], [w / 2, -length]]])


def _blob(p: dict, seg: int) -> np.ndarray:
    """Star-shaped free form r(t) = radius * (1 + sum amp * cos(k t + phase))."""
    r0 = float(p["radius"])
    t = 2 * np.pi * np.arange(seg) / seg
    rel = np.ones_like(t)
    for k, amp, phase_deg in p["harmonics"]:
        rel += float(amp) * np.cos(int(k) * t + np.deg2rad(float(phase_deg)))
    if rel.min() <= 0.1:
        raise FeederError("blob harmonics make the radius (nearly) vanish")
    return np.column_stack([r0 * rel * np.cos(t), r0 * rel * np.sin(t)])


RANDPOLY_RADIUS_CLIP = (0.3, 1.7)  # randpoly: radius factors are kept in this range (no spikes to 0)


def _randpoly(p: dict, seg: int) -> np.ndarray:
    """A random star-shaped polygon about the origin, seeded (``seed``): ``n`` vertices at angles
    spaced 2π/n times a factor drawn from [1 - irregularity, 1 + irregularity] (rescaled to a full
    turn), at radii ``radius`` times a factor drawn from N(1, spikiness) clipped to
    [RANDPOLY_RADIUS_CLIP]. Star-shaped, so always simple."""
    n, r0 = int(p["n"]), float(p["radius"])
    irregularity, spikiness = float(p["irregularity"]), float(p["spikiness"])
    if n < 3 or not 0 <= irregularity < 1 or spikiness < 0:
        raise FeederError("randpoly needs n >= 3, 0 <= irregularity < 1 and spikiness >= 0")
    rng = np.random.default_rng(int(p["seed"]))
    steps = rng.uniform(1 - irregularity, 1 + irregularity, n)
    angles = rng.uniform(0, 2 * np.pi) + np.cumsum(2 * np.pi * steps / steps.sum())
    radii = r0 * np.clip(rng.normal(1.0, spikiness, n), *RANDPOLY_RADIUS_CLIP)
    return np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])


def _randblob(p: dict, seg: int) -> np.ndarray:
    """A random star-shaped free form, seeded (``seed``): a :func:`_blob` whose ``harmonics``
    distinct orders are drawn from 1..``max_order``, with amplitudes drawn from [0, 1] scaled so
    that they sum to ``amplitude`` and phases drawn from [0, 360)."""
    count, top = int(p["harmonics"]), int(p["max_order"])
    amplitude = float(p["amplitude"])
    if not 1 <= count <= top or not 0 < amplitude < 1:
        raise FeederError("randblob needs 1 <= harmonics <= max_order and 0 < amplitude < 1")
    rng = np.random.default_rng(int(p["seed"]))
    orders = np.sort(rng.choice(np.arange(1, top + 1), size=count, replace=False))
    weights = rng.uniform(0.0, 1.0, count)
    amps = amplitude * weights / weights.sum()
    phases = rng.uniform(0.0, 360.0, count)
    harmonics = [[int(k), float(a), float(ph)] for k, a, ph in zip(orders, amps, phases, strict=True)]
    return _blob({"radius": p["radius"], "harmonics": harmonics}, seg)


FAMILIES: dict[str, Callable[[dict, int], np.ndarray]] = {
    "ngon": _ngon,
    "triangle": _triangle,
    "rect": _rect,
    "rrect": _rrect,
    "ellipse": _ellipse,
    "ibeam": _ibeam,
    "lshape": _lshape,
    "tshape": _tshape,
    "ushape": _ushape,
    "zshape": _zshape,
    "hat": _hat,
    "cross": _cross,
    "crescent": _crescent,
    "star": _star,
    "gear": _gear,
    "keyhole": _keyhole,
    "blob": _blob,
    "randpoly": _randpoly,
    "randblob": _randblob,
}
HOLE_SHAPES = {"circle": 3, "rect": 4}  # a hole entry of `holes`: its shape and how many numbers it takes


def family_outline(family: str, params: dict, circle_segments: int) -> np.ndarray:
    """Outline in mm (CCW, bounding box lower-left at the origin) of one family member."""
    if family not in FAMILIES:
        raise FeederError(f"unknown part family {family!r} (known: {', '.join(sorted(FAMILIES))})")
    params = dict(params)
    params.pop("holes", None)  # placed after the outline (library_holes)
    rotation = float(params.pop("rotation_deg", 0.0))
    try:
        pts = np.asarray(FAMILIES[family](params, circle_segments), dtype=np.float64)
    except KeyError as err:
        raise FeederError(f"family {family} is missing parameter {err.args[0]!r}") from err
    if rotation:
        c, s = math.cos(math.radians(rotation)), math.sin(math.radians(rotation))
        pts = pts @ np.array([[c, s], [-s, c]])
    pts = pts - pts.min(axis=0)
    # exact zeros stay zeros; tiny negative rounding cannot appear after the shift
    return pts


# --------------------------------------------------------------------------------------------
# Shape metrics (catalog)
# --------------------------------------------------------------------------------------------
def library_holes(entries, segments: int) -> list[np.ndarray]:
    """The through-holes (mm, CCW) of a part's ``holes`` entries, placed in its outline's frame
    (bounding box lower-left at the origin): ``{circle: [cx, cy, r]}`` (``segments`` vertices) or
    ``{rect: [cx, cy, width, height]}`` (axis-aligned)."""
    holes = []
    for k, entry in enumerate(entries or (), start=1):
        if not isinstance(entry, dict) or len(entry) != 1 or next(iter(entry)) not in HOLE_SHAPES:
            raise FeederError(f"hole {k} must be one of {', '.join(f'{{{s}: [...]}}' for s in HOLE_SHAPES)}")
        shape, values = next(iter(entry.items()))
        try:
            v = [float(x) for x in values]
        except (TypeError, ValueError):
            raise FeederError(f"hole {k}: {shape} takes {HOLE_SHAPES[shape]} numbers") from None
        if len(v) != HOLE_SHAPES[shape] or any(x <= 0 for x in v[2:]):
            raise FeederError(f"hole {k}: {shape} takes {HOLE_SHAPES[shape]} numbers, sizes positive")
        if shape == "circle":
            t = 2 * np.pi * np.arange(segments) / segments
            holes.append(np.column_stack([v[0] + v[2] * np.cos(t), v[1] + v[2] * np.sin(t)]))
        else:
            cx, cy, hw, hh = v[0], v[1], v[2] / 2, v[3] / 2
            holes.append(np.array([(cx - hw, cy - hh), (cx + hw, cy - hh), (cx + hw, cy + hh), (cx - hw, cy + hh)]))
    return holes


def shape_metrics(outline: np.ndarray, holes=()) -> dict[str, float]:
    """Area, perimeter, aspect ratio (min-area bounding rectangle), convexity, compactness and
    eigen ratio (largest / smallest eigenvalue of the central second-moment-of-area tensor), of
    the outline's region less its ``holes`` (the perimeter counts the holes' edges too)."""
    import shapely

    from feeder.parts.geometry import polygon_moments, profile_moments

    poly = shapely.Polygon(outline)
    if len(holes):
        area, _, (ixx, iyy, ixy) = profile_moments(np.asarray(outline), holes)
    else:
        area, _, (ixx, iyy, ixy) = polygon_moments(np.asarray(outline))
    perim = float(poly.length) + sum(float(shapely.LinearRing(h).length) for h in holes)
    rect = np.asarray(shapely.minimum_rotated_rectangle(poly).exterior.coords)[:4]
    sides = np.linalg.norm(np.diff(np.vstack([rect, rect[:1]]), axis=0), axis=1)
    aspect = float(max(sides[0], sides[1]) / min(sides[0], sides[1]))
    ev = np.linalg.eigvalsh(np.array([[iyy, ixy], [ixy, ixx]]))
    return {
        "area": float(area),
        "perimeter": perim,
        "aspect_ratio": aspect,
        "convexity": float(area / poly.convex_hull.area),
        "compactness": float(4 * math.pi * area / perim**2),
        "eigen_ratio": float(ev[1] / ev[0]),
    }


# --------------------------------------------------------------------------------------------
# The generator
# --------------------------------------------------------------------------------------------
def load_spec(spec_path: str | Path) -> dict[str, Any]:
    import yaml

    spec_path = Path(spec_path)
    try:
        spec = yaml.safe_load(spec_path.read_text())
    except OSError as err:
        raise FeederError(f"{spec_path}: cannot read ({err.strerror})") from err
    except yaml.YAMLError as err:
        raise FeederError(f"{spec_path}: invalid YAML ({str(err).splitlines()[0]})") from err
    if not isinstance(spec, dict) or "parts" not in spec or "limits" not in spec:
        raise FeederError(f"{spec_path}: needs top-level 'limits', 'cloud' and 'parts' entries")
    ids = [p.get("id") for p in spec["parts"]]
    dup = sorted({i for i in ids if ids.count(i) > 1})
    if dup:
        raise FeederError(f"{spec_path}: duplicate part ids {', '.join(map(str, dup))}")
    return spec


def build_part(entry: dict, spec: dict) -> dict[str, Any]:
    """Outline (mm), thickness (mm), face cloud (mm) and catalog row of one library entry."""
    from feeder.parts.geometry import _check_holes, clean_holes, clean_outline, face_cloud, thinnest_wall

    lim, cloud = spec["limits"], spec["cloud"]
    pid = str(entry.get("id"))
    if not LIBRARY_ID_RE.match(pid):
        raise FeederError(f"part id {pid!r}: use lowercase letters, digits and '-' only")
    thickness = float(entry["thickness_mm"])
    if not lim["thickness_mm"][0] <= thickness <= lim["thickness_mm"][1]:
        raise FeederError(f"part {pid}: thickness {thickness} mm outside {lim['thickness_mm']}")
    params = entry.get("params", {})
    try:
        outline = clean_outline(family_outline(entry["family"], params, int(spec["circle_segments"])))
    except FeederError as err:
        raise FeederError(f"part {pid}: {err}") from err
    holes = []
    if params.get("holes"):
        if "hole_segments" not in spec or "min_wall_mm" not in lim:
            raise FeederError(f"part {pid} has holes: the library needs hole_segments and limits.min_wall_mm")
        try:
            holes = clean_holes(library_holes(params["holes"], int(spec["hole_segments"])))
            _check_holes(outline, holes, "holes")
        except FeederError as err:
            raise FeederError(f"part {pid}: {err}") from err
        wall = thinnest_wall(outline, holes)
        if wall < float(lim["min_wall_mm"]):
            raise FeederError(f"part {pid}: a wall round a hole is {wall:.2f} mm < limits.min_wall_mm")
    size = float(np.max(np.ptp(outline, axis=0)))
    if not lim["size_mm"][0] <= size <= lim["size_mm"][1]:
        raise FeederError(f"part {pid}: in-plane size {size:.1f} mm outside {lim['size_mm']}")
    if len(outline) > lim["max_vertices"]:
        raise FeederError(f"part {pid}: {len(outline)} vertices > limits.max_vertices")
    metrics = shape_metrics(outline, holes)
    area_cm2 = metrics["area"] / 100.0
    n_target = int(np.clip(round(cloud["points_per_cm2"] * area_cm2), cloud["min_points"], cloud["max_points"]))
    pts = face_cloud(outline, n_target, holes)
    if not lim["points"][0] <= len(pts) <= lim["points"][1]:
        raise FeederError(f"part {pid}: face cloud has {len(pts)} points, outside the cloud limits")
    m = shape_metrics(outline / 1000.0, [h / 1000.0 for h in holes])  # catalog in SI units (m, m^2)
    row = {
        "id": pid,
        "family": entry["family"],
        "params": json.dumps(params, sort_keys=True),
        "thickness": thickness / 1000.0,
        "size": size / 1000.0,
        "n_points": len(pts),
        "n_vertices": len(outline),
        **m,
    }
    return {"id": pid, "outline_mm": outline, "holes_mm": holes, "thickness_mm": thickness, "cloud_mm": pts, "row": row}


def xyz_text(cloud_mm: np.ndarray, z_mm: float) -> str:
    """The ``x y z`` lines of a face cloud, mm, 4 decimals (like a CAD export)."""
    z = np.full((len(cloud_mm), 1), z_mm)
    arr = np.hstack([cloud_mm, z])
    return "".join(f"{x:.4f} {y:.4f} {zz:.4f}\n" for x, y, zz in arr)


def generate(spec_path: str | Path, out_dir: str | Path, progress: bool = True) -> list[str]:
    """Write every part's STL and XYZ and the catalog; return the ids."""
    import pandas as pd
    from tqdm import tqdm

    from feeder.io import write_bytes, write_csv, write_text
    from feeder.parts.geometry import stl_bytes

    spec = load_spec(spec_path)
    out_dir = Path(out_dir)
    rows = []
    built = []
    for entry in tqdm(spec["parts"], desc="parts", disable=not (progress and sys.stderr.isatty())):
        built.append(build_part(entry, spec))  # validate everything before writing anything
    for b in built:
        holes_m = [h / 1000.0 for h in b["holes_mm"]]
        write_bytes(
            out_dir / f"{b['id']}.stl",
            stl_bytes(b["outline_mm"] / 1000.0, b["thickness_mm"] / 1000.0, b["id"], holes=holes_m),
        )
        write_text(out_dir / f"{b['id']}.xyz", xyz_text(b["cloud_mm"], b["thickness_mm"]))
        rows.append(b["row"])
    frame = pd.DataFrame(rows, columns=CATALOG_COLUMNS).sort_values("id", kind="stable")
    write_csv(out_dir / "catalog.csv", frame)
    return [b["id"] for b in built]


def diversity_summary(catalog) -> dict[str, int]:
    """Counts of the library diversity criteria (see parts/library.yaml)."""
    return {
        "parts": int(len(catalog)),
        "families": int(catalog["family"].nunique()),
        "highly_concave(convexity<0.75)": int((catalog["convexity"] < 0.75).sum()),
        "elongated(aspect_ratio>=4)": int((catalog["aspect_ratio"] >= 4).sum()),
        "near_symmetric(eigen_ratio<1.05)": int((catalog["eigen_ratio"] < 1.05).sum()),
    }


# --------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------
def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="feeder parts", description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    g = sub.add_parser("generate", help="write parts/<id>.stl, <id>.xyz and catalog.csv")
    g.add_argument("--spec", default="parts/library.yaml")
    g.add_argument("--out", default="parts")
    x = sub.add_parser("xyz", help="derive the face point cloud (.xyz, mm) of an STL")
    x.add_argument("stl")
    x.add_argument("--out", required=True)
    x.add_argument("--points", type=int, required=True, help="number of points (about)")
    x.add_argument(
        "--units",
        default="auto",
        choices=("auto", "m", "mm"),
        help="units of the STL; auto: millimetres if the part would be wider than 1 m, else metres",
    )
    li = sub.add_parser("list", help="print the part ids")
    li.add_argument("--dir", default="parts")
    li.add_argument("--include", nargs="*", default=None)
    f = sub.add_parser("fig6-data", help="outlines and their DFT reconstructions (Fig. 6 panel b data, .npz)")
    f.add_argument("paths", nargs="+", help=".xyz or .stl files, one panel each")
    f.add_argument("--out", required=True)
    f.add_argument(
        "--coefficients",
        type=int,
        default=None,
        help="coefficients kept (default: the feature count, feeder.parts.features.DFT)",
    )
    s = sub.add_parser("s1", help="reconstruction MSE vs number of coefficients (Fig. S1 table)")
    s.add_argument("paths", nargs="+", help=".xyz or .stl files of the library")
    s.add_argument("--table", required=True)
    s.add_argument("--max-coefficients", type=int, required=True)
    return ap


def main(argv: list[str]) -> int:
    args = _parser().parse_args(argv)
    if args.cmd == "generate":
        import pandas as pd

        from feeder.config import project_path

        ids = generate(project_path(args.spec), args.out)
        summary = diversity_summary(pd.read_csv(Path(args.out) / "catalog.csv"))
        print(json.dumps({"generated": len(ids), **summary}))
        return 0
    if args.cmd == "xyz":
        from feeder.io import write_text
        from feeder.parts.geometry import face_cloud, load_part

        if args.points < 1:
            raise FeederError(f"--points must be positive, got {args.points}")
        g = load_part(args.stl, args.units)
        pts = face_cloud(g.outline * 1000.0, args.points, [h * 1000.0 for h in g.holes])
        write_text(args.out, xyz_text(pts, g.thickness * 1000.0))
        return 0
    if args.cmd == "list":
        from feeder.config import project_path

        print("\n".join(list_parts(project_path(args.dir), args.include if args.include else "all")))
        return 0
    if args.cmd == "fig6-data":
        from feeder.io import write_npz
        from feeder.parts.features import DFT, reconstruction_data

        count = DFT.coefficients if args.coefficients is None else args.coefficients
        write_npz(args.out, **reconstruction_data(args.paths, count))
        return 0
    if args.cmd == "s1":
        from feeder.io import write_csv
        from feeder.parts.features import study_mse

        write_csv(args.table, study_mse(args.paths, args.max_coefficients))
        return 0
    raise AssertionError(args.cmd)  # pragma: no cover
