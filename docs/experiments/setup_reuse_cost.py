"""Bench (issue #38 item 3, 2026-11-25, session 26): what does building each drop's world in one
reused pybullet client, with the configuration's plan made once, save per simulation job, and does
it change any output? Not part of the workflow. From the repository root:

    git worktree add /tmp/before <commit before the change>   # OLD_SRC = /tmp/before/src
    .venv/bin/python docs/experiments/setup_reuse_cost.py CONFIGS_CSV OLD_SRC OUT_RAW.csv [N] [SEED] [JOBS] [NEW_SRC]

Runs a seeded sample of N (default 60) of the study's configurations (``part, loc1, loc2`` rows of a
run's ``results/datasets/configurations.csv``) through ``feeder simulate`` exactly as the workflow's
default does (adaptive, budget ``sim.drops``, preset ``sim.preset``, config/config.yaml), once with
the code of ``OLD_SRC`` and once with this checkout's ``src``, in alternating order. Writes one raw
row per run (the process's CPU seconds inside the simulation, ``cpu_s`` of the output, and SHA-256
digests of the final yaws, statuses and initial yaws), then prints the paired summary: the CPU
ratio new/old with a 95 % bootstrap interval over configurations, and how many outputs are equal
bit for bit. ``JOBS`` 2 runs the sample two jobs at a time, as ``make run`` on two cores does
(configurations in pairs, both of a pair under one version at once, the versions' order alternating
by pair); the default 1 runs one job at a time, the other core left to whatever else runs.
``NEW_SRC``: the code after the change (default: this checkout's ``src``).
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

ROOT = Path(__file__).resolve().parents[2]
DIGESTS = ("final_sha", "status_sha", "initial_sha")


def run_one(src: Path, row, cfg: dict, out: Path) -> dict:
    cmd = [sys.executable, "-m", "feeder", "simulate", "--part", f"parts/{row.part}.stl"]
    cmd += ["--loc1", row.loc1, "--loc2", row.loc2, "--drops", str(cfg["sim"]["drops"])]
    cmd += ["--seed", str(cfg["sim"]["base_seed"]), "--yaw-sampling", "adaptive", "--preset", cfg["sim"]["preset"]]
    cmd += ["--out", str(out)]
    env = dict(os.environ, PYTHONPATH=str(src))
    subprocess.run(cmd, cwd=ROOT, env=env, check=True, capture_output=True)
    d = np.load(out, allow_pickle=True)

    def sha(a) -> str:
        return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()[:16]

    return {
        "cpu_s": float(d["cpu_s"]),
        "wall_s": float(d["wall_s"]),
        "drops": int(len(d["status"])),
        "final_sha": sha(d["final_yaw_deg"]),
        "status_sha": sha(d["status"]),
        "initial_sha": sha(d["initial_yaw_deg"]),
    }


def main(argv: list[str]) -> int:
    configs, old_src, out_csv = Path(argv[0]), Path(argv[1]), Path(argv[2])
    n = int(argv[3]) if len(argv) > 3 else 60
    seed = int(argv[4]) if len(argv) > 4 else 0
    cfg = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    table = pd.read_csv(configs).drop_duplicates(["part", "loc1", "loc2"])
    sample = table.sample(n=min(n, len(table)), random_state=seed).reset_index(drop=True)
    jobs = int(argv[5]) if len(argv) > 5 else 1
    versions = {"before": old_src, "after": Path(argv[6]) if len(argv) > 6 else ROOT / "src"}
    rows = []
    items = list(sample.itertuples())
    groups = [items[i : i + jobs] for i in range(0, len(items), jobs)]
    with tempfile.TemporaryDirectory() as tmp, ThreadPoolExecutor(max_workers=jobs) as pool:
        for g, group in enumerate(groups):
            order = ["before", "after"] if g % 2 == 0 else ["after", "before"]
            for v in order:
                futures = [
                    pool.submit(run_one, versions[v], row, cfg, Path(tmp) / f"{v}{k}.npz")
                    for k, row in enumerate(group)
                ]
                for row, fut in zip(group, futures, strict=True):
                    rows.append({"part": row.part, "loc1": row.loc1, "loc2": row.loc2, "version": v, **fut.result()})
            print(f"{g + 1}/{len(groups)} {[(r.part, r.loc1, r.loc2) for r in group]}", file=sys.stderr, flush=True)
    raw = pd.DataFrame(rows)
    out_csv.parent.mkdir(parents=True, exist_ok=True)
    raw.to_csv(out_csv, index=False)
    summarize(raw)
    return 0


def summarize(raw: pd.DataFrame, boot: int = 10000, seed: int = 0) -> None:
    key = ["part", "loc1", "loc2"]
    wide = raw.pivot_table(index=key, columns="version", values="cpu_s")
    same = raw.pivot_table(index=key, columns="version", values=list(DIGESTS), aggfunc="first")
    equal = sum(
        all(same[(c, "before")].iloc[i] == same[(c, "after")].iloc[i] for c in DIGESTS) for i in range(len(same))
    )
    b, a = wide["before"].to_numpy(), wide["after"].to_numpy()
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, len(b), size=(boot, len(b)))
    ratios = a[idx].sum(axis=1) / b[idx].sum(axis=1)
    lo, hi = np.quantile(ratios, [0.025, 0.975])
    print(f"configurations {len(b)}; outputs equal bit for bit: {equal}/{len(b)}")
    print(f"CPU-s in the simulation: before {b.sum():.1f}, after {a.sum():.1f}")
    print(f"ratio after/before {a.sum() / b.sum():.3f} [{lo:.3f}, {hi:.3f}] (95 % bootstrap over configurations)")
    drops = raw[raw.version == "after"].drops.sum()
    print(f"saved per job: {np.mean(b - a):.3f} s (mean), per drop {1000 * (b - a).sum() / drops:.1f} ms")


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--summary":
        summarize(pd.read_csv(sys.argv[2]))
        sys.exit(0)
    sys.exit(main(sys.argv[1:]))
