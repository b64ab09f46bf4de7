"""Would partial exit turns give the candidates the simulator's basins? (issue #39, unseen parts)

The candidates' ceiling (``structured_ceiling.py``) is worst on one straight fence at steep
angles: at 50-60 deg only 35-54 % of the label lies within 5 deg of any analytic variant's mode.
A rectangle on a straight fence leaves in modes that drift with the fence angle (rect-a2: 182,
174, 168 deg at 20, 35, 40 deg), between the variants "exit turn" and "no exit turn". This script
adds the modes of variants whose exit turn is scaled by each of ``SCALES`` (the flush yaw plus
that share of the modelled turn; the part's other fence responses unchanged) and asks how far the
oracle of ``structured_ceiling.py`` falls with them, against a control that adds as many
positions drawn at random (seeded by the configuration), so that more positions alone are not
counted as a gain.

    python docs/experiments/exit_scale_ceiling.py results/datasets/dataset.npz \
        results/datasets/structured_candidates.npz parts results/tables/exit_scale_ceiling.csv

Writes one row per configuration and candidate set (raw) and prints the per-part means (what
GroupKFold averages) and the means by fence types.
"""

from __future__ import annotations

import hashlib
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
from structured_ceiling import oracle_pmf

from feeder import io
from feeder.circular import wrap360
from feeder.labels.dataset import load_dataset
from feeder.labels.metrics import circular_w1
from feeder.lane.fences import parse_config_id
from feeder.mechanics.candidates import candidates_from_pmfs
from feeder.mechanics.distribution import analytic_distribution
from feeder.mechanics.fence import default_scene, fence_models, fence_mu
from feeder.mechanics.hull import push_geometry
from feeder.mechanics.pmf import bin_masses
from feeder.parts.geometry import load_profile

SCALES = (0.25, 0.5, 0.75)  # shares of the modelled exit turn
MIN_MASS, WINDOW_DEG, MERGE_DEG = 0.01, 5.0, 2.0  # config/hydra/structured.yaml candidates


def scaled_memo(memo: dict, scale: float) -> dict:
    """The part's fence responses with each exit turn scaled by ``scale`` (flush yaw + scale x turn)."""
    out = {}
    for key, resp in memo.items():
        delta = np.mod(resp.exit_deg - resp.rest_deg + 180.0, 360.0) - 180.0
        out[key] = replace(resp, exit_deg=wrap360(resp.rest_deg + scale * delta))
    return out


def scaled_modes(geom, memo, loc1, loc2, scene, frame_deg, bins) -> np.ndarray:
    mu = fence_mu(scene)
    fences = fence_models(loc1, loc2, scene)
    analytic_distribution(geom, None, None, scene, mu=mu, fences=fences, responses=memo)  # fill the memo
    pmfs = []
    for s in SCALES:
        d = analytic_distribution(geom, None, None, scene, mu=mu, fences=fences, responses=scaled_memo(memo, s))
        if d.weights.sum() <= 0:
            d = analytic_distribution(
                geom, None, None, scene, mu=mu, fences=fences, responses=scaled_memo(memo, s), jams=False
            )
        h = bin_masses(d.yaws + frame_deg, d.weights, bins)
        pmfs.append(h / h.sum())
    pos, _ = candidates_from_pmfs(np.stack(pmfs), MIN_MASS, WINDOW_DEG, MERGE_DEG, 32)
    return pos


def main(argv: list[str]) -> int:
    dataset, cache, parts_dir, out = Path(argv[0]), Path(argv[1]), Path(argv[2]), Path(argv[3])
    data = load_dataset(dataset)
    settings = json.loads(str(data["settings"]))
    scene = settings.get("scene") or default_scene()
    units = str((settings.get("parts") or {}).get("units", "auto"))
    with np.load(cache, allow_pickle=False) as z:
        k, pos, analytic = z["k"], z["pos"], z["analytic"]
    n = len(data["part"])
    pmf = np.asarray(data["pmf"], dtype=np.float64)
    pmf = pmf / pmf.sum(axis=1, keepdims=True)
    bins = pmf.shape[1]
    parts, cids = (np.asarray(data[key]).astype(str) for key in ("part", "config_id"))
    frames = np.asarray(data["frame_deg"], dtype=np.float64)
    geoms, memos, rows = {}, {}, []
    for i in range(n):
        p = parts[i]
        if p not in geoms:
            outline, holes, _ = load_profile(Path(parts_dir) / f"{p}.stl", units)
            geoms[p], memos[p] = push_geometry(outline, holes), {}
            if len(geoms) % 10 == 1:
                print(f"part {len(geoms)} ({p})", file=sys.stderr, flush=True)
        loc1, loc2 = parse_config_id(cids[i])
        cand = pos[i, : k[i]]
        extra = scaled_modes(geoms[p], memos[p], loc1, loc2, scene, float(frames[i]), bins)
        near = np.array([np.min(np.abs(np.mod(cand - e + 180.0, 360.0) - 180.0)) > MERGE_DEG for e in extra], bool)
        new = extra[near] if cand.size else extra
        seed = int(hashlib.sha256(f"{p}:{cids[i]}".encode()).hexdigest()[:8], 16)
        rand = np.random.default_rng(seed).uniform(0.0, 360.0, new.size)
        label_cdf = np.cumsum(pmf[i])
        for name, positions in (
            ("candidates", cand),
            ("plus_scaled_exit", np.concatenate([cand, new])),
            ("plus_random", np.concatenate([cand, rand])),
        ):
            q, share = oracle_pmf(pmf[i], analytic[i], positions)
            rows.append(
                {
                    "part": p,
                    "config_id": cids[i],
                    "split": str(data["split"][i]),
                    "candidate_set": name,
                    "positions": int(np.size(positions)),
                    "added": int(new.size),
                    "covered_mass": share,
                    "oracle_cw1_deg": float(circular_w1(label_cdf, np.cumsum(q))),
                }
            )
    frame = pd.DataFrame(rows)
    io.write_csv(out, frame)
    per_part = frame.groupby(["candidate_set", "part"]).oracle_cw1_deg.mean().groupby("candidate_set").mean()
    print("per-part mean oracle cW1 (deg):")
    print(per_part.to_string())
    frame["types"] = frame.config_id.str.replace(r"\d+", "", regex=True)
    print(frame.pivot_table(index="types", columns="candidate_set", values="oracle_cw1_deg").round(2).to_string())
    print(frame.groupby("candidate_set")[["added", "covered_mass"]].mean().to_string())
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
