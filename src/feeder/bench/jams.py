"""Which fence angles jam parts (``feeder bench-jams``): the survey behind the fence grid.

A fence holds a part for ever where its surface faces the belt's motion too squarely (sliding
needs tan β > μ, β the angle between the belt velocity and the fence normal; pybullet's part-fence
μ is 0.8 × 0.5 = 0.4, so β > 21.8°). Every curved fence has such a zone around its most
upstream point; whether a part reaches it depends on the angle and the part. The survey runs every
fence type × angle of its own lists (``sim.jam_survey``: the whole allowed range, so it shows why
the grid in ``fences`` leaves some angles out) alone at each location over a few library parts
and reports the share of drops that end ``ok`` and ``jammed``, so the grid can
leave out angles that jam most drops (configurations with too few ok drops are excluded from the
datasets anyway, see ``labels.on_bad``: they cost simulation time and give no label).

Writes one row per (fence, location, part) plus ``part = mean`` rows.
"""

from __future__ import annotations

import argparse
import sys
from multiprocessing import get_context

import numpy as np
import pandas as pd

from feeder.errors import FeederError


def survey_jobs(angles: dict, parts: list[str]) -> list[tuple[str, str, str]]:
    """``(loc1, loc2, part)`` for every single fence (``angles``: ``straight_angles`` and
    ``curved_angles`` lists) at each location and every part."""
    jobs = []
    for kind in ("straight", "curved"):
        for angle in angles[f"{kind}_angles"]:
            spec = f"{kind}:{float(angle):g}"
            for loc1, loc2 in ((spec, "none"), ("none", spec)):
                jobs.extend((loc1, loc2, p) for p in parts)
    return jobs


def _run(job):
    loc1, loc2, part, parts_dir, drops, seed, scene, preset, name = job
    from feeder.lane.fences import parse_location
    from feeder.parts.geometry import load_part
    from feeder.sim.drops import STATUSES
    from feeder.sim.simulate import simulate

    geom = load_part(f"{parts_dir}/{part}.stl")
    res = simulate(geom, parse_location(loc1), parse_location(loc2), drops, seed, scene, preset, name)
    return loc1, loc2, part, {s: float(np.mean(res["status"] == s)) for s in STATUSES}


def summarize(rows: list[tuple[str, str, str, dict]]) -> pd.DataFrame:
    """Per-part rows and ``part = mean`` rows (mean over parts) per fence and location."""
    recs = []
    for loc1, loc2, part, shares in rows:
        spec, location = (loc1, "loc1") if loc1 != "none" else (loc2, "loc2")
        kind, angle = spec.split(":")
        recs.append(
            {
                "fence": kind,
                "angle_deg": float(angle),
                "location": location,
                "part": part,
                **{f"{k}_rate": v for k, v in shares.items()},
            }
        )
    df = pd.DataFrame(recs).sort_values(["fence", "angle_deg", "location", "part"], ignore_index=True)
    rate_cols = [c for c in df.columns if c.endswith("_rate")]
    mean = df.groupby(["fence", "angle_deg", "location"], as_index=False)[rate_cols].mean()
    mean["part"] = "mean"
    return pd.concat([df, mean[df.columns]], ignore_index=True)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder bench-jams", description=__doc__.splitlines()[0])
    parser.add_argument("--settings", required=True, help="JSON {scene, sim, parts} config sections")
    parser.add_argument("--out-csv", required=True)
    args = parser.parse_args(argv)
    from feeder.config import parse_settings

    cfg = parse_settings(args.settings, "scene", "sim", "parts")
    try:
        scene, sim_cfg = cfg["scene"], cfg["sim"]
        survey, parts_dir = sim_cfg["jam_survey"], cfg["parts"]["dir"]
    except (KeyError, TypeError) as err:
        raise FeederError(f"--settings lacks {err}") from None
    from feeder.sim.drops import get_preset

    preset = get_preset(sim_cfg["presets"], survey["preset"])
    drops = int(survey["drops"])
    if drops < 1:
        raise FeederError(f"sim.jam_survey.drops must be positive, got {drops}")
    jobs = [
        (l1, l2, p, parts_dir, drops, int(sim_cfg["base_seed"]), scene, preset, survey["preset"])
        for l1, l2, p in survey_jobs(survey, list(survey["parts"]))
    ]
    bar = None
    if sys.stderr.isatty():
        from tqdm import tqdm

        bar = tqdm(total=len(jobs), unit="run", file=sys.stderr)
    rows = []
    with get_context("fork").Pool(max(1, int(survey["workers"]))) as pool:
        for row in pool.imap_unordered(_run, jobs):
            rows.append(row)
            if bar is not None:
                bar.update(1)
    if bar is not None:
        bar.close()
    df = summarize(rows)
    from feeder.io import write_csv

    write_csv(args.out_csv, df)
    worst = df[df["part"] == "mean"].sort_values("ok_rate").head(6)
    for _, r in worst.iterrows():
        print(
            f"{r['fence']:>8} {r['angle_deg']:4.0f} {r['location']}: ok {r['ok_rate']:.2f}, "
            f"jammed {r['jammed_rate']:.2f}",
            file=sys.stderr,
        )
    return 0
