"""A one-fence label read at the other location: the mirror image of the scene.

Location 1 stands on the right of the belt and Location 2 on the left; a part riding the belt does
not change between them. So the scene ``F | none`` seen by a part P, reflected x → −x, is the
scene ``none | F`` seen by P's mirror image, every final yaw negated (``feeder bench-mirror``,
``results/tables/mirror_locations.csv``). A part with a mirror axis is its own mirror image,
turned by ``t = 180° − 2α`` (α the axis, :func:`feeder.parts.symmetry.mirror_axis`), so one of its
labels serves both locations:

    label[F | none](y) = label[none | F](t − y)        (yaws in the part's frame)

In the label frame (yaw + ``frame_deg``) the constant is ``t + 2 · frame_deg``
(:func:`label_mirror_deg`). On the study's 132 pairs of one-fence labels of a symmetric part at the
two locations within 5° of each other, the reflected label lies 1.5° (circular W1) from the other,
against 24.6° unreflected (``docs/experiments/mirror_labels.py``).

:func:`with_mirrors` appends, to the rows a neighbour is looked up among, each one-fence label of
a part with a mirror axis read at the other location (``model.mirror_labels``): a known part's
labels at Location 1 become neighbours of its queries at Location 2, and back.
"""

from __future__ import annotations

import math

import numpy as np

from feeder.errors import FeederError

FULL_TURN_DEG = 360.0
HALF_TURN_DEG = 180.0
# the per-row arrays a neighbour is read from (feeder.learn.structured_data.neighbour_block, basin_components,
# feeder.learn.structured_blend.gated_pmfs): the PMFs among them are reflected, the rest copied
MIRROR_PMFS = ("pmf", "analytic", "base_analytic")
MIRROR_COPIES = ("part", "kept", "ok", "analytic_ok", "frame_deg", "mirror_deg")


def mirror_config_id(config_id: str) -> str | None:
    """The configuration with the one fence of ``config_id`` at the other location
    (``straight30_none`` ↔ ``none_straight30``), None for two fences or none."""
    from feeder.lane.fences import config_id as make_id
    from feeder.lane.fences import parse_config_id

    a, b = parse_config_id(str(config_id))
    if a.present == b.present:
        return None
    return make_id(b, a)


def label_mirror_deg(outline, holes, frame_deg: float, tolerance: float | None = None) -> float:
    """The constant ``c`` of ``label[F | none](y) = label[none | F](c − y)`` for a part of this
    outline with labels in a frame ``frame_deg`` from the part's (module doc), in [0, 360); NaN
    when the part has no mirror axis within ``tolerance`` (the symmetry module's default)."""
    from feeder.parts.symmetry import DEFAULT_SYMMETRY_TOLERANCE, mirror_axis

    if not math.isfinite(float(frame_deg)):
        raise FeederError(f"frame_deg must be finite, got {frame_deg!r}")
    axis = mirror_axis(outline, DEFAULT_SYMMETRY_TOLERANCE if tolerance is None else tolerance, holes)
    if axis is None:
        return math.nan
    return float((HALF_TURN_DEG - 2.0 * axis + 2.0 * float(frame_deg)) % FULL_TURN_DEG)


def reflect_pmf(pmf, mirror_deg: float) -> np.ndarray:
    """The PMF of ``mirror_deg − yaw`` given the PMF of ``yaw`` (circular, along the last axis):
    bin ``k`` (centre ``(k + ½) w``) goes to the bin of ``−(k + ½) w``, then the whole moves by
    ``mirror_deg`` (:func:`feeder.labels.metrics.shift_pmf`: exact for whole bins, mass split
    linearly between two bins otherwise)."""
    from feeder.labels.metrics import shift_pmf

    p = np.asarray(pmf, dtype=np.float64)
    bins = p.shape[-1]
    return shift_pmf(p[..., (-np.arange(bins) - 1) % bins], float(mirror_deg))


def with_mirrors(arrays: dict, pool) -> tuple[dict, np.ndarray, np.ndarray]:
    """The rows a neighbour is looked up among, with the mirrored ones appended.

    ``arrays`` holds per-row ``part``, ``config_id``, the PMFs of :data:`MIRROR_PMFS` and the
    fields of :data:`MIRROR_COPIES` that it has, and ``mirror_deg`` (:func:`label_mirror_deg`, NaN
    for a part without a mirror axis); ``pool`` (a boolean mask) the labelled rows. Every pool row
    with one fence and a finite ``mirror_deg`` gives one more row: its configuration at the other
    location (:func:`mirror_config_id`), its PMFs reflected (:func:`reflect_pmf`), the rest
    copied, ``cdf`` its PMF's. Returns (those fields over the ``N`` rows then the ``M`` mirrored
    ones, the pool over them (every mirrored row in it), the source row of each mirrored row
    (M,)). Without ``mirror_deg`` in ``arrays``, ``M`` is 0 and the fields are ``arrays``'."""
    n = len(arrays["part"])
    pool = np.asarray(pool, dtype=bool)
    if pool.shape != (n,):
        raise FeederError(f"with_mirrors: a pool of shape {pool.shape} for {n} rows")
    keys = [k for k in ("config_id", *MIRROR_PMFS, *MIRROR_COPIES) if k in arrays]
    base = {k: np.asarray(arrays[k]) for k in keys}
    if "pmf" in base:
        base["cdf"] = np.asarray(arrays["cdf"]) if "cdf" in arrays else np.cumsum(base["pmf"], axis=1)
    src, ids = [], []
    if "mirror_deg" in arrays:
        turn = np.asarray(arrays["mirror_deg"], dtype=np.float64)
        for j in np.flatnonzero(pool & np.isfinite(turn)):
            other = mirror_config_id(arrays["config_id"][j])
            if other is not None:
                src.append(int(j))
                ids.append(other)
    src = np.asarray(src, dtype=np.int64)
    if not src.size:
        return base, pool, src
    out = {}
    for key, a in base.items():
        if key == "cdf":
            continue
        if key == "config_id":
            out[key] = np.concatenate([a.astype(str), np.asarray(ids, dtype=str)])
        elif key in MIRROR_PMFS:
            turn = np.asarray(arrays["mirror_deg"], dtype=np.float64)
            extra = np.stack([reflect_pmf(a[j], turn[j]) for j in src])
            out[key] = np.concatenate([a, extra])
        else:
            out[key] = np.concatenate([a, a[src]])
    if "pmf" in out:
        out["cdf"] = np.concatenate([base["cdf"], np.cumsum(out["pmf"][n:], axis=1)])
    return out, np.concatenate([pool, np.ones(src.size, dtype=bool)]), src


def mirror_labels(cfg) -> bool:
    """``model.mirror_labels`` of ``config/hydra/structured.yaml`` (absent: false), checked."""
    value = cfg.model.get("mirror_labels", False)
    if not isinstance(value, bool):
        raise FeederError(f"model.mirror_labels must be true or false, got {value!r}")
    return value


def part_mirror_degs(parts, frames, parts_dir, units: str) -> np.ndarray:
    """Per row, :func:`label_mirror_deg` of its part (the STL ``parts_dir/<part>.stl`` read in
    ``units``) in its label frame ``frames``; each part's outline is read once."""
    from pathlib import Path

    from feeder.parts.geometry import load_profile

    of: dict[tuple[str, float], float] = {}
    out = np.empty(len(parts), dtype=np.float64)
    for n, (part, frame) in enumerate(zip(parts, frames, strict=True)):
        key = (str(part), float(frame))
        if key not in of:
            path = Path(parts_dir) / f"{part}.stl"
            if not path.is_file():
                raise FeederError(f"part file {path} is missing (model.mirror_labels needs every part's outline)")
            outline, holes, _ = load_profile(path, units)
            of[key] = label_mirror_deg(outline, holes, frame)
        out[n] = of[key]
    return out
