"""Where does a part first meet a curved fence? The disc estimate against the hull's exact contact.

The analytic model decides whether a drop jams on a curved fence by the local fence angle where it
first meets the arc (its *entry*), estimated by a disc of the part's lateral support radius
(``feeder.mechanics.distribution._apply``). Stop 64 found one curved fence at 50° jamming 31 % of the
initial yaws that the simulator lets through. This script computes the exact first contact instead:
the part's convex hull at its yaw, translated along the travel direction from its lateral position,
meets the arc's face circle first either with a hull vertex or with a hull edge tangent to the
circle; the local angle there is the exact entry. A contact beyond the arc's tip grazes the tip
(the model leaves the drop as it was), one before the slot end takes the slot's angle. Then, drop by
drop against the simulator's status (the same initial yaws, centred as the simulator drops them, the
first fence met only, so the lateral position is exact), it scores the jam decision of both rules:
the share of the initial yaws (cell weights as in ``analytic_dropwise.py``) where the model's
"jams" agrees with the simulator's ``jammed``, by fence type and angle.

    python docs/experiments/exact_entry.py SIM_DIR PARTS_DIR OUT_CSV_GZ

Rows (gzipped CSV): one per drop whose first fence met is curved; the summary goes beside them as
``<name>_summary.csv``. About 20 seconds on one core.
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads: OpenBLAS's AVX2 kernel (feeder/__init__.py)

# isort: on
import argparse
import gzip
import sys
from pathlib import Path

import numpy as np
import pandas as pd

import feeder.mechanics.distribution as D
from feeder.io import write_bytes, write_csv
from feeder.mechanics.fence import fence_models, fence_mu, friction_margin_deg

sys.path.insert(0, str(Path(__file__).parent))
from analytic_dropwise import cell_weights, sim_files  # noqa: E402


def _rotated(hull: np.ndarray, yaw_deg: np.ndarray) -> np.ndarray:
    """(N, H, 2) hull vertices at each yaw (world directions, about the centroid)."""
    a = np.radians(yaw_deg)[:, None]
    c, s = np.cos(a), np.sin(a)
    return np.stack([c * hull[None, :, 0] - s * hull[None, :, 1], s * hull[None, :, 0] + c * hull[None, :, 1]], -1)


def exact_entry(geom, model, yaw_deg: np.ndarray, x: np.ndarray):
    """For each drop (yaw, lateral centroid x), moving along +y: the outward normal angle (world,
    degrees, seen from the arc's centre) of the arc's face circle at the hull's first contact, and
    whether the hull meets the circle at all. Vertex contacts: the lower intersection of the vertex's
    path with the circle; edge contacts: the circle's point whose outward normal is opposite the
    edge's, where it lies within the edge. The first contact is the earliest (smallest centroid y)."""
    cx, cy = model.centre
    R = model.outer_radius
    v = _rotated(geom.hull, yaw_deg)  # (N, H, 2)
    px = x[:, None] + v[..., 0] - cx
    disc = R * R - px * px
    y_vertex = np.where(disc >= 0.0, cy - v[..., 1] - np.sqrt(np.clip(disc, 0.0, None)), np.inf)
    # edges: outward normal n of edge i (world), contact point q = C - R n; centroid y with the edge through q
    a = np.radians(geom.normals_deg[None, :] + yaw_deg[:, None])
    nx, ny = np.cos(a), np.sin(a)
    qx, qy = cx - R * nx, cy - R * ny
    va, vb = v, np.roll(v, -1, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        # the edge passes through q: n . (q - (p + va)) = 0 with p = (x, y)
        y_edge = (nx * (qx - x[:, None] - va[..., 0]) + ny * (qy - va[..., 1])) / ny
        # where q lies along the edge (0..1) once placed
        ex, ey = vb[..., 0] - va[..., 0], vb[..., 1] - va[..., 1]
        t = ((qx - x[:, None] - va[..., 0]) * ex + (qy - y_edge - va[..., 1]) * ey) / (ex * ex + ey * ey)
    ok = (ny > 1e-12) & (t >= 0.0) & (t <= 1.0)  # the edge faces +y (towards the circle ahead)
    y_edge = np.where(ok, y_edge, np.inf)
    yv, iv = y_vertex.min(axis=1), y_vertex.argmin(axis=1)
    ye, ie = y_edge.min(axis=1), y_edge.argmin(axis=1)
    rows = np.arange(len(yaw_deg))
    use_edge = ye < yv
    # contact point on the circle
    cpx = np.where(use_edge, qx[rows, ie], x + v[rows, iv, 0])
    cpy = np.where(use_edge, qy[rows, ie], np.minimum(yv, ye) + v[rows, iv, 1])
    normal = np.degrees(np.arctan2(cpy - cy, cpx - cx))
    return normal, np.isfinite(np.minimum(yv, ye))


def local_angle(model, normal_deg: np.ndarray) -> np.ndarray:
    """The local fence angle at the arc point of outward normal ``normal_deg``: the disc rule's
    ``acos(side · (C_x − x_p) / |p − C|)`` with the contact normal in place of the centroid's."""
    return np.degrees(np.arccos(np.clip(-model.side * np.cos(np.radians(normal_deg)), -1.0, 1.0)))


def decisions(geom, model, mu, yaw, x):
    """Per drop: (touch, graze, jam) under the disc rule and under the exact contact."""
    reach = D._support_towards(geom, yaw, model.side)
    touch = model.side * x + reach > model.inner
    cos_a = model.side * (model.centre[0] - x) / (model.outer_radius + reach)
    disc = np.degrees(np.arccos(np.clip(cos_a, -1.0, 1.0)))
    normal, met = exact_entry(geom, model, yaw, x)
    exact = np.where(met, local_angle(model, normal), np.nan)
    out = {}
    for name, entry in (("disc", disc), ("exact", exact)):
        graze = ~(entry >= model.exit_deg)  # NaN (no contact) grazes
        t = touch & ~graze
        e = np.minimum(np.nan_to_num(entry, nan=model.exit_deg), model.slot_deg)
        jam = t & (friction_margin_deg(e, mu) < 0.0)
        out[name] = (t, graze & touch, jam, e)
    return out


def rows_for(sim_dir: Path, parts_dir: Path) -> pd.DataFrame:
    rows = []
    for part, geom, path, meta, scene, period, y0, _, status in sim_files(sim_dir, parts_dir):
        fences = fence_models(meta["loc1"], meta["loc2"], scene)
        if fences and fences[0].curved:
            m = fences[0]
            mu = fence_mu(scene)
            w = cell_weights(y0, period)
            d = decisions(geom, m, mu, np.asarray(y0, dtype=np.float64), np.zeros(len(y0)))
            for i in range(len(y0)):
                rows.append(
                    (
                        part,
                        path.stem,
                        f"curved:{m.fence.angle:g}",
                        len(fences),
                        y0[i],
                        w[i],
                        status[i],
                        *(bool(d[k][j][i]) for k in ("disc", "exact") for j in range(3)),
                        d["disc"][3][i],
                        d["exact"][3][i],
                    )
                )
    cols = ["part", "config_id", "fence", "n_fences", "initial_yaw_deg", "weight", "status"]
    cols += [f"{k}_{j}" for k in ("disc", "exact") for j in ("touch", "graze", "jam")] + ["disc_entry", "exact_entry"]
    return pd.DataFrame(rows, columns=cols)


def summary(df: pd.DataFrame) -> pd.DataFrame:
    df = df.assign(sim_jam=df.status == "jammed")
    out = []
    for (fence, n), g in df.groupby(["fence", "n_fences"]):
        w = g.weight / g.weight.sum()
        rec = {"fence": fence, "n_fences": n, "configurations": len(g.groupby(["part", "config_id"]))}
        rec["sim_jam"] = float((w * g.sim_jam).sum())
        for k in ("disc", "exact"):
            rec[f"{k}_jam"] = float((w * g[f"{k}_jam"]).sum())
            rec[f"{k}_agree"] = float((w * (g[f"{k}_jam"] == g.sim_jam)).sum())
            rec[f"{k}_graze"] = float((w * g[f"{k}_graze"]).sum())
        out.append(rec)
    return pd.DataFrame(out)


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sim_dir", type=Path)
    ap.add_argument("parts_dir", type=Path)
    ap.add_argument("out_csv", type=Path)
    a = ap.parse_args(argv)
    df = rows_for(a.sim_dir, a.parts_dir)
    write_bytes(a.out_csv, gzip.compress(df.to_csv(index=False, lineterminator="\n").encode(), mtime=0))
    s = summary(df)
    write_csv(a.out_csv.with_name(a.out_csv.name.split(".")[0] + "_summary.csv"), s)
    pd.set_option("display.width", 200)
    print(s.round(3).to_string(index=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
