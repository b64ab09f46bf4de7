"""How far and how fast does a fence turn a part? (issue #39, unseen parts)

Two questions on one measurement. Both came from crescent-b on ``straight:15``: in the simulator
it keeps the yaw it arrives with over φ ≈ 227–257° of its outer arc, and drops from a further 200°
of yaws stop at the first of those orientations. The analytic model finds no stable edge on that
arc under the fence's friction (``mu = 0.4``: the foot shifted by ``mu · d`` falls just past each
short edge) and sends every drop round to the chord between the horns (about 105° of circular W1).

1. Is the friction that turns a part the friction that jams it? ``push:S`` scales the push
   function's friction alone by ``S``; ``turn:S`` scales it wherever the part turns (push function,
   rolling density, arc ride, exit turn); the jam rule keeps the scene's ``mu``.
2. Does a part turn at the rate of its own moment arm? The turn budget lets a fence turn a part by
   ``o / (2c)`` for an overlap ``o``, the fastest rate any contact turns it, and the short way to
   its stable edge. ``moment:B`` turns it at the contact's own rate
   (:mod:`feeder.mechanics.turnrate`: slow where the line of force passes near the centroid), the
   way the push function flows, within the budget ×``B``; ``bound:B`` is the bound's rule ×``B``.
3. Are the basin boundaries where the push function puts them? ``bounds:K`` turns them from the
   vertex directions by ``K · atan(mu)`` instead of ``atan(mu)`` (stability unchanged).

4. Does a contact patch hold a rolling arc? (stop 71) ``patch:G``: an edge the push function
   finds unstable holds where the shifted foot lies within the hull's boundary ``G`` mm from the
   edge's line (``push_function(..., patch_gap=...)``); ``arcpatch:G`` the same, edges longer than
   :data:`ARC_EDGE_MAX` circumradii keeping themselves as their patch.

5. What does a steep curved fence do to a part its arc misses? (stop 71) ``graze:face`` and
   ``graze:swing``: ``analytic_distribution(..., graze=...)`` (:data:`feeder.mechanics.distribution.GRAZE`).

6. Whole-model settings, for ``part_calibration.py`` (stop 72; :data:`WHOLE_MODEL`, ``pmf`` only):
   ``mu:X`` the part-fence friction everywhere, ``budget:B`` the turn budget ×B, ``noexit``,
   ``nojams``, ``ride:M`` the arc ride (``none``, ``basin``, ``state``).

``base`` is the default model. Measured as ``arc_ride.py`` does:

``drops``: every simulated drop of a configuration whose fences roll the part in no mode, pushed
through the model from its own initial yaw (hard jams; agree within ``AGREE_DEG`` modulo the
period, or both jam; weighted by its share of the initial yaws); summary by fence types.

``pmf``: the analytic PMF's circular W1 to the label of every kept configuration, per split,
paired by configuration with a 95 % bootstrap over parts, restarted for each mode (choose on
``train`` alone).

    python docs/experiments/fence_turns.py drops SIM_DIR PARTS_DIR OUT_CSV_GZ --modes base,moment:3
    python docs/experiments/fence_turns.py pmf DATASET PARTS_DIR OUT_CSV_GZ --modes base,push:0.75
    python docs/experiments/fence_turns.py summary DROPS_CSV_GZ PMF_CSV_GZ OUT_PREFIX

About 5 minutes a mode for ``pmf`` and 3 for ``drops`` on one core. Nothing is fitted.
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads: OpenBLAS's AVX2 kernel (feeder/__init__.py)

# isort: on
import argparse
import contextlib
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from analytic_dropwise import AGREE_DEG, cell_weights, sim_files  # noqa: E402
from arc_ride import _gap, pmf_summary  # noqa: E402

import feeder.mechanics.distribution as D  # noqa: E402
import feeder.mechanics.pushfunction as PF  # noqa: E402
from feeder.io import write_csv  # noqa: E402
from feeder.labels.dataset import load_dataset  # noqa: E402
from feeder.labels.metrics import circular_w1  # noqa: E402
from feeder.lane.fences import parse_config_id  # noqa: E402
from feeder.learn.evaluate import fence_types  # noqa: E402
from feeder.mechanics.fence import fence_models, fence_mu  # noqa: E402
from feeder.mechanics.hull import as_geometry  # noqa: E402
from feeder.mechanics.pmf import analytic_pmf  # noqa: E402
from feeder.parts.geometry import load_part  # noqa: E402

MM = 1e-3  # metres per millimetre (patch:S gives the gap in mm)
# Modes that set one of analytic_distribution's own arguments for the whole model (stop 72, for
# part_calibration.py): mu:X the part-fence friction everywhere (jams included), budget:B the turn
# budget ×B, noexit no exit turn, nojams no jam, ride:M the arc ride (none, basin, state). pmf only.
WHOLE_MODEL = {
    "mu": lambda s: {"mu": float(s)},
    "budget": lambda s: {"turn_budget_scale": float(s)},
    "noexit": lambda s: {"exit_turns": False},
    "nojams": lambda s: {"jams": False},
    "ride": lambda s: {"arc_ride": None if s == "none" else s},
}
ARC_EDGE_MAX = 0.15  # arcpatch:S: edges longer than this (circumradii) are flat, their patch the edge
_ORIG = {name: getattr(D, name) for name in ("push_function", "rolling_density", "arc_yaw", "exit_turn")}
_ORIG["contact_patch"] = PF.contact_patch


def options(name: str) -> dict:
    """``analytic_distribution``'s turn options of a mode: ``moment:B``/``bound:B``, the turn rate
    (:data:`feeder.mechanics.distribution.TURN_RATE`) with the turn budget ×B; else the defaults."""
    what, _, scale = name.partition(":")
    if what in ("moment", "bound"):
        return dict(turn_rate="moment" if what == "moment" else None, turn_budget_scale=float(scale), graze=D.GRAZE)
    out = dict(turn_rate=D.TURN_RATE, turn_budget_scale=D.TURN_BUDGET_SCALE, graze=D.GRAZE)
    if what == "graze":
        out["graze"] = scale
    elif what in WHOLE_MODEL:  # analytic_distribution's own arguments (pmf only: see final_yaws)
        out.update(WHOLE_MODEL[what](scale))
    return out


@contextlib.contextmanager
def mode(name: str):
    """Patch ``feeder.mechanics.distribution`` so the named friction uses ``mu · S``."""
    what, _, scale = name.partition(":")
    if what in ("base", "moment", "bound", "graze", *WHOLE_MODEL):
        yield
        return
    s = float(scale)
    if what in ("patch", "arcpatch"):  # also held where the shifted foot lies within the patch of gap S mm
        patched = {"push_function": lambda g, mu, side: _ORIG["push_function"](g, mu, side, patch_gap=s * MM)}
        if what == "arcpatch":  # edges longer than ARC_EDGE_MAX circumradii keep the edge as their patch
            patched["contact_patch"] = _arc_patch
    elif what == "bounds":  # the boundaries turned from the vertex directions by S · atan(mu)
        patched = {
            "push_function": lambda g, mu, side: _ORIG["push_function"](
                g, mu, side, boundary_mu=math.tan(s * math.atan(mu))
            )
        }
    else:
        patched = {"push_function": lambda g, mu, side: _ORIG["push_function"](g, mu * s, side)}
    if what == "turn":
        patched["rolling_density"] = lambda g, mu, side, phi: _ORIG["rolling_density"](g, mu * s, side, phi)
        patched["arc_yaw"] = lambda g, m, y, x, mu, memo=None: _ORIG["arc_yaw"](g, m, y, x, mu * s, memo)
        patched["exit_turn"] = lambda g, e, a, side, mu, **kw: _ORIG["exit_turn"](g, e, a, side, mu * s, **kw)
    elif what not in ("push", "bounds", "patch", "arcpatch"):
        raise SystemExit(f"unknown mode {name!r}")
    for k, f in patched.items():
        setattr(PF if k == "contact_patch" else D, k, f)
    try:
        yield
    finally:
        for k in patched:
            setattr(PF if k == "contact_patch" else D, k, _ORIG[k])


def _arc_patch(geom, gap):
    """:func:`feeder.mechanics.pushfunction.contact_patch`, the edge itself for edges longer than
    :data:`ARC_EDGE_MAX` circumradii (a patch only on polygonised arcs)."""
    lo, hi = _ORIG["contact_patch"](geom, gap)
    flat = geom.lengths > ARC_EDGE_MAX * geom.circumradius
    return np.where(flat, 0.0, lo), np.where(flat, geom.lengths, hi)


def final_yaws(geom, fences, yaws, mu, memo, name: str = "base") -> np.ndarray:
    """Final yaw of each drop (NaN: jammed) through ``fences`` in order under mode ``name``, hard
    jams; ValueError where a fence rolls the part."""
    if name.partition(":")[0] in WHOLE_MODEL:
        raise SystemExit(f"mode {name!r} is for pmf only (final_yaws pushes with the scene's own settings)")
    opt = options(name)
    yaw = np.asarray(yaws, dtype=np.float64).copy()
    x = np.zeros_like(yaw)
    tag = np.arange(1.0, yaw.size + 1.0)
    for m in fences:
        if m not in memo:
            memo[m] = D.fence_response(geom, m, mu, True)
        if memo[m].push.rolls:
            raise ValueError("a fence rolls the part: no yaw per drop")
        yaw, x, tag, _ = D._apply(
            geom,
            memo[m],
            mu,
            yaw,
            x,
            tag,
            True,
            0.0,
            opt["turn_budget_scale"],
            D.ARC_RIDE,
            memo,
            opt["turn_rate"],
            opt["graze"],
        )
    out = np.full(len(yaws), np.nan)
    out[np.rint(tag).astype(int) - 1] = yaw
    return out


def drops(sim_dir: Path, parts_dir: Path, modes: list[str]) -> pd.DataFrame:
    rows = []
    memos: dict = {m: {} for m in modes}
    for part, geom, path, meta, scene, period, y0, yf, status in sim_files(sim_dir, parts_dir):
        loc1, loc2 = meta["loc1"], meta["loc2"]
        fences = fence_models(loc1, loc2, scene)
        mu = fence_mu(scene)
        out = {}
        try:
            for m in modes:
                with mode(m):
                    out[m] = final_yaws(geom, fences, y0, mu, memos[m].setdefault((part, mu), {}), m)
        except ValueError:
            continue
        w = cell_weights(np.mod(y0, period), period)
        rows.append(
            pd.DataFrame(
                dict(
                    part=part,
                    config_id=path.stem,
                    loc1=loc1,
                    loc2=loc2,
                    period=period,
                    initial_yaw_deg=y0,
                    weight=w,
                    status=status.astype(str),
                    final_yaw_deg=yf,
                    **{f"yaw_{m}": out[m] for m in modes},
                )
            )
        )
    return pd.concat(rows, ignore_index=True)


def mode_pmf(geom, config_id: str, frame_deg: float, name: str, memo: dict) -> np.ndarray:
    """The analytic PMF of a configuration in the label frame under mode ``name`` (``memo``: the
    part's responses under that mode); where every drop jams, the PMF without jams."""
    loc1, loc2 = parse_config_id(config_id)
    with mode(name):
        dist = D.analytic_distribution(geom, loc1, loc2, responses=memo, **options(name))
        if dist.weights.sum() <= 0.0:
            dist = D.analytic_distribution(geom, loc1, loc2, responses=memo, **{**options(name), "jams": False})
    return analytic_pmf(geom, loc1, loc2, frame_deg=frame_deg, distribution=dist)


def pmfs(dataset: Path, parts_dir: Path, modes: list[str]) -> pd.DataFrame:
    data = load_dataset(dataset)
    geoms: dict = {}
    memos: dict = {m: {} for m in modes}
    rows = []
    for i, (part, config_id) in enumerate(zip(data["part"], data["config_id"])):
        part, config_id = str(part), str(config_id)
        if part not in geoms:
            geoms[part] = as_geometry(load_part(parts_dir / f"{part}.stl"))
        for m in modes:
            pmf = mode_pmf(geoms[part], config_id, float(data["frame_deg"][i]), m, memos[m].setdefault(part, {}))
            cw1 = float(circular_w1(np.cumsum(pmf), data["cdf"][i]))
            rows.append((m, part, config_id, str(data["split"][i]), cw1))
    return pd.DataFrame(rows, columns=["mode", "part", "config_id", "split", "circular_w1_deg"])


def drop_summary(d: pd.DataFrame, modes: list[str]) -> pd.DataFrame:
    ok = d.status == "ok"
    for m in modes:
        y = d[f"yaw_{m}"]
        d[f"agree_{m}"] = (ok & y.notna() & (_gap(d.final_yaw_deg, y.fillna(0.0), d.period) <= AGREE_DEG)) | (
            ~ok & y.isna()
        )
    d["wn"] = d.weight / d.groupby(["part", "config_id"]).weight.transform("sum")
    d["group"] = [fence_types(c) for c in d.config_id]
    per = d.groupby(["group", "part", "config_id"]).apply(
        lambda g: pd.Series({m: float((g.wn * g[f"agree_{m}"]).sum()) for m in modes}), include_groups=False
    )
    per = per.reset_index()
    out = per.groupby("group")[modes].mean()
    out.insert(0, "configs", per.groupby("group").size())
    tot = per[modes].mean().to_frame().T
    tot.insert(0, "configs", len(per))
    tot.index = ["all"]
    return pd.concat([out, tot]).reset_index(names="fences")


def pmf_summary_per_mode(raw: pd.DataFrame) -> pd.DataFrame:
    """:func:`pmf_summary` of each mode against ``base`` on its own (the bootstrap restarted per
    mode, so a mode's interval does not depend on which other modes the table holds), sorted by
    split and mode."""
    modes = sorted(m for m in raw["mode"].unique() if m != "base")
    parts = [pmf_summary(raw[raw["mode"] == "base"], ["base"], "base")]
    parts += [pmf_summary(raw[raw["mode"].isin(["base", m])], [m], "base") for m in modes]
    out = pd.concat(parts, ignore_index=True)
    order = {s: i for i, s in enumerate(out.split.unique())}
    key = out.split.map(order) * (len(modes) + 1) + out["mode"].map({m: i for i, m in enumerate(["base", *modes])})
    return out.iloc[np.argsort(key.to_numpy(), kind="stable")].reset_index(drop=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=["drops", "pmf", "summary"])
    ap.add_argument("a", type=Path)
    ap.add_argument("b", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--modes", default="base,push:0.5,push:0.75,turn:0.5,turn:0.75")
    args = ap.parse_args(argv)
    modes = args.modes.split(",")
    if args.what == "drops":
        d = drops(args.a, args.b, modes)
        d.to_csv(args.out, index=False)
        print(drop_summary(d, modes).to_string(index=False))
    elif args.what == "pmf":
        raw = pmfs(args.a, args.b, modes)
        raw.to_csv(args.out, index=False)
        print(pmf_summary(raw, modes, "base").to_string(index=False))
    else:
        d = pd.read_csv(args.a)
        modes = [c[4:] for c in d.columns if c.startswith("yaw_")]
        ds = drop_summary(d, modes)
        raw = pd.read_csv(args.b)
        ps = pmf_summary_per_mode(raw)
        write_csv(f"{args.out}_drops.csv", ds)
        write_csv(f"{args.out}_pmf.csv", ps)
        print(ds.to_string(index=False))
        print(ps.to_string(index=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
