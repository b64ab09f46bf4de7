"""Test and benchmark parts from short specs (independent of the part library).

A spec is ``<family>-<numbers in mm separated by x>`` so it is also a valid part id:

* ``rect-WxH``: rectangle W × H;
* ``ngon-NxR``: regular N-gon of circumradius R;
* ``ellipse-AxB``: ellipse with semi-axes A, B (48 vertices);
* ``c-WxHxT``: C (U) shape, outer W × H, wall T, open towards +x;
* ``l-WxHxT``: L shape, legs W and H, wall T;
* ``t-WxHxT``: T shape, bar W, stem H, wall T;
* ``star-NxROxRI``: N-pointed star, outer / inner radius;
* ``tri-WxH``: right triangle with legs W, H;
* ``washer-ROxRI``: a disc of radius RO (32 vertices) with a round through-hole of radius RI
  (16 vertices) at its centre;
* ``plate-WxHxD``: rectangle W × H with a square through-hole D × D centred at (W/4, H/2), a
  bracket with a bolt hole near one end (its centre of mass is off the outline's centroid).

``shape_part(spec, thickness_m)`` returns a :class:`feeder.parts.geometry.PartGeometry`;
``mirror_part(geom)`` its left/right mirror image (x → −x).
"""

from __future__ import annotations

import numpy as np

from feeder.errors import FeederError


def outline_mm(spec: str) -> np.ndarray:
    """Outline vertices (mm, CCW) of a shape spec."""
    try:
        family, dims = spec.split("-", 1)
        v = [float(s) for s in dims.split("x")]
    except ValueError:
        raise FeederError(f"shape spec {spec!r} is not <family>-<n>x<n>...") from None

    def need(n):
        if len(v) != n or any(x <= 0 for x in v):
            raise FeederError(f"shape spec {spec!r}: {family} takes {n} positive numbers")

    if family == "rect":
        need(2)
        w, h = v
        return np.array([(0, 0), (w, 0), (w, h), (0, h)], float)
    if family == "ngon":
        need(2)
        n, r = int(v[0]), v[1]
        a = 2 * np.pi * np.arange(n) / n
        return np.stack([r * np.cos(a), r * np.sin(a)], 1)
    if family == "ellipse":
        need(2)
        a = 2 * np.pi * np.arange(48) / 48
        return np.stack([v[0] * np.cos(a), v[1] * np.sin(a)], 1)
    if family == "c":
        need(3)
        w, h, t = v
        return np.array([(0, 0), (w, 0), (w, t), (t, t), (t, h - t), (w, h - t), (w, h), (0, h)], float)
    if family == "l":
        need(3)
        w, h, t = v
        return np.array([(0, 0), (w, 0), (w, t), (t, t), (t, h), (0, h)], float)
    if family == "t":
        need(3)
        w, h, t = v
        c = 0.5 * w
        return np.array(
            [
                (c - t / 2, 0),
                (c + t / 2, 0),
                (c + t / 2, h - t),
                (w, h - t),
                (w, h),
                (0, h),
                (0, h - t),
                (c - t / 2, h - t),
            ],
            float,
        )
    if family == "star":
        need(3)
        n, ro, ri = int(v[0]), v[1], v[2]
        a = np.pi * np.arange(2 * n) / n
        r = np.where(np.arange(2 * n) % 2 == 0, ro, ri)
        return np.stack([r * np.cos(a), r * np.sin(a)], 1)
    if family == "tri":
        need(2)
        return np.array([(0, 0), (v[0], 0), (0, v[1])], float)
    if family == "washer":
        need(2)
        return _circle(v[0], WASHER_OUTER_VERTICES)
    if family == "plate":
        need(3)
        return outline_mm(f"rect-{dims.rsplit('x', 1)[0]}")
    raise FeederError(f"shape spec {spec!r}: unknown family {family!r}")


WASHER_OUTER_VERTICES, WASHER_HOLE_VERTICES = 32, 16


def _circle(radius: float, vertices: int) -> np.ndarray:
    a = 2 * np.pi * np.arange(vertices) / vertices
    return np.stack([radius * np.cos(a), radius * np.sin(a)], 1)


def holes_mm(spec: str) -> list[np.ndarray]:
    """Through-holes (mm, CCW) of a shape spec (none for the simply connected families); the spec
    is checked by :func:`outline_mm`."""
    outline_mm(spec)
    family, dims = spec.split("-", 1)
    v = [float(s) for s in dims.split("x")]
    if family == "washer":
        if not v[1] < v[0]:
            raise FeederError(f"shape spec {spec!r}: the hole radius must be below the outer radius")
        return [_circle(v[1], WASHER_HOLE_VERTICES)]
    if family == "plate":
        w, h, d = v
        if not (d < h and d < w / 2):
            raise FeederError(f"shape spec {spec!r}: the hole must fit inside the plate (D < H and D < W/2)")
        cx, cy = w / 4, h / 2
        return [
            np.array(
                [(cx - d / 2, cy - d / 2), (cx + d / 2, cy - d / 2), (cx + d / 2, cy + d / 2), (cx - d / 2, cy + d / 2)]
            )
        ]
    return []


def shape_part(spec: str, thickness: float):
    from feeder.parts.geometry import PartGeometry

    holes = [h / 1000.0 for h in holes_mm(spec)]
    return PartGeometry.from_polygon(spec, outline_mm(spec) / 1000.0, thickness, holes)


def mirror_part(geom, part_id: str | None = None):
    """The mirror image x → −x (outline and holes reversed to stay CCW)."""
    from feeder.parts.geometry import PartGeometry

    flip = np.array([-1.0, 1.0])
    pts = np.asarray(geom.outline, float) * flip
    holes = [(np.asarray(h, float) * flip)[::-1] for h in geom.holes]
    return PartGeometry.from_polygon(part_id or f"{geom.part_id}-m", pts[::-1], geom.thickness, holes)


def mod180_dist(a, b):
    """Distance between two axial angles (mod 180), degrees in [0, 90]."""
    d = np.mod(np.asarray(a, float) - np.asarray(b, float), 180.0)
    return np.minimum(d, 180.0 - d)
