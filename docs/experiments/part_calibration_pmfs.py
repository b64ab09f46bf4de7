"""The calibrated analytic model as PMFs, and mixed with the part's nearest label (issue #39)

``part_calibration.py`` chooses each known part's analytic mode from circular W1 tables alone. This
script makes the PMFs, so that the calibrated answer can be mixed with the part's own labels:

``pmfs``: every dataset row's analytic PMF (label frame, as ``fence_turns.py pmf`` builds it) under
each mode of ``--modes``, to one npz (float32, rows × modes × bins; about 5 CPU-minutes per mode).

``mix``: for every Test and Fences row of ``part_calibration_rows.csv``, the calibrated PMF (the
rule of ``part_calibration.py``, family ``base`` plus the npz's modes, the margin its Test rule
chose, from ``part_calibration_rules.csv``) and
``w · label + (1 − w) · calibrated``, with ``label`` the part's nearest training label of the same
fence types (``|Δθ1| + |Δθ2|``) and ``w = exp(−distance / τ)`` (0 with no such label). ``τ`` is
chosen on training rows alone, each answered from the part's other training rows. The rows are
paired with the protocol's analytic PMF, the structured predictor and the gated neighbour with the
calibrated fallback (95 % bootstrap over configurations, each averaged over its repeats).

    python docs/experiments/part_calibration_pmfs.py pmfs results/datasets/dataset.npz parts \
        results/datasets/mode_pmfs.npz --modes base,graze:swing,mu:0.5,...
    python docs/experiments/part_calibration_pmfs.py mix results/datasets/dataset.npz \
        results/datasets/mode_pmfs.npz results/tables/part_calibration

``mix`` reads ``<prefix>_rows.csv`` and the raw W1 tables of ``part_calibration.py`` and writes
``<prefix>_mix_rows.csv`` and ``<prefix>_mix_summary.csv`` (seconds).
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads (feeder/__init__.py)

# isort: on
import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
import fence_turns as F  # noqa: E402
import part_calibration as P  # noqa: E402

from feeder import io  # noqa: E402
from feeder.io import write_csv  # noqa: E402
from feeder.labels.dataset import load_dataset  # noqa: E402
from feeder.labels.metrics import circular_w1  # noqa: E402
from feeder.learn.structured_data import nearest_rows  # noqa: E402
from feeder.mechanics.hull import as_geometry  # noqa: E402
from feeder.parts.geometry import load_part  # noqa: E402

TAUS_DEG = (0.0, 5.0, 10.0, 20.0, 40.0, 80.0)  # 0: the calibrated PMF alone
RAW_TABLES = ("fence_turns_pmf.csv.gz", "part_calibration_pmf.csv.gz")
PAIRS = (
    ("mix", "structured"),
    ("mix", "analytic_protocol"),
    ("mix", "gated_calibrated"),
    ("calibrated_pmf", "analytic_protocol"),
    ("calibrated_pmf", "structured"),
)


def mode_pmfs(dataset: Path, parts_dir: Path, modes: list[str], limit: int | None = None) -> np.ndarray:
    data = load_dataset(dataset)
    n = len(data["part"]) if limit is None else min(int(limit), len(data["part"]))
    bins = data["cdf"].shape[1]
    out = np.zeros((n, len(modes), bins), np.float32)
    geoms: dict = {}
    memos: dict = {m: {} for m in modes}
    for i in range(n):
        part, cid = str(data["part"][i]), str(data["config_id"][i])
        if part not in geoms:
            geoms[part] = as_geometry(load_part(parts_dir / f"{part}.stl"))
        for j, m in enumerate(modes):
            out[i, j] = F.mode_pmf(geoms[part], cid, float(data["frame_deg"][i]), m, memos[m].setdefault(part, {}))
        if i % 200 == 0:
            print(f"row {i} of {n}", file=sys.stderr, flush=True)
    return out


class Mixer:
    def __init__(self, dataset: Path, npzs: list[Path], tables: Path):
        self.data = load_dataset(dataset)
        self.modes, pmfs = [], []
        for path in npzs:  # their modes joined
            with np.load(path, allow_pickle=False) as z:
                self.modes += [str(m) for m in z["modes"]]
                pmfs.append(z["pmf"].astype(np.float64))
        self.pmf = np.concatenate(pmfs, axis=1)
        if P.BASE not in self.modes:
            raise SystemExit(f"no {P.BASE!r} mode in {', '.join(map(str, npzs))}")
        self.row = {(str(p), str(c)): i for i, (p, c) in enumerate(zip(self.data["part"], self.data["config_id"]))}
        w1, self.rows = P.load([tables / t for t in RAW_TABLES], tables / "structured_rows.csv")
        self.family = [P.BASE, *[m for m in self.modes if m != P.BASE]]
        rules = pd.read_csv(tables / "part_calibration_rules.csv").fillna({"chosen_for": ""})
        self.margin = float(rules.loc[rules.chosen_for.str.contains("test"), "margin_deg"].iloc[0])
        self.w1 = w1[self.family]
        self.train = P.training_sets(self.w1, self.rows)

    def check(self, count: int = 20) -> float:
        """Largest |W1 of a stored PMF − the raw table's| over the first ``count`` rows."""
        worst = 0.0
        for (part, cid), i in list(self.row.items())[:count]:
            for j, m in enumerate(self.modes):
                w = float(circular_w1(np.cumsum(self.pmf[i, j]), self.data["cdf"][i]))
                worst = max(worst, abs(w - self.w1.loc[(part, cid), m]))
        return worst

    def nearest(self, part: str, cid: str, pool: list[str]) -> tuple[float, str | None]:
        """The part's nearest configuration of ``pool`` of the same fence types (the protocol's
        :func:`feeder.learn.structured_data.nearest_rows`) and its angle distance."""
        mask = np.zeros(len(self.data["part"]), dtype=bool)
        mask[[self.row[(part, c)] for c in pool]] = True
        idx, dist = nearest_rows(self.data["part"], self.data["config_id"], mask, [self.row[(part, cid)]], 1)
        return float(dist[0, 0]), None if idx[0, 0] < 0 else str(self.data["config_id"][idx[0, 0]])

    def answer(self, part: str, cid: str, pool: list[str], tau: float) -> tuple[float, float, str]:
        """(the mix's W1, the calibrated PMF's W1, the mode) for ``part`` at ``cid`` from its
        training configurations ``pool``."""
        mine = self.w1.loc[[(part, c) for c in pool]]
        mode = P.choose(mine, self.family, self.margin)
        i = self.row[(part, cid)]
        cal = self.pmf[i, self.modes.index(mode)]
        d, nb = self.nearest(part, cid, pool)
        w = 0.0 if nb is None or tau <= 0.0 else float(np.exp(-d / tau))
        mix = cal if nb is None else w * self.data["pmf"][self.row[(part, nb)]] + (1.0 - w) * cal
        cdf = self.data["cdf"][i]
        return float(circular_w1(np.cumsum(mix), cdf)), float(circular_w1(np.cumsum(cal), cdf)), mode

    def choose_tau(self) -> pd.DataFrame:
        out = []
        for idx in self.train.values():
            for part, g in self.w1.loc[idx].groupby(level="part"):
                cids = [c for _, c in g.index]
                for cid in cids:
                    others = [c for c in cids if c != cid]
                    out += [(tau, self.answer(part, cid, others, tau)[0]) for tau in TAUS_DEG]
        return pd.DataFrame(out, columns=["tau_deg", "w1"]).groupby("tau_deg").w1.mean().reset_index()

    def scored(self, scored: pd.DataFrame, tau: float) -> pd.DataFrame:
        out = scored.copy()
        res = []
        for _, r in scored.iterrows():
            pool = [c for p, c in self.train[int(r["repeat"])] if p == r.part]
            res.append(self.answer(r.part, r.config_id, pool, tau))
        out["mix"], out["calibrated_pmf"], out["pmf_mode"] = zip(*res)
        return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="what", required=True)
    a = sub.add_parser("pmfs")
    a.add_argument("dataset", type=Path)
    a.add_argument("parts_dir", type=Path)
    a.add_argument("out", type=Path)
    a.add_argument("--modes", required=True)
    a.add_argument("--limit", type=int, default=None, help="the first rows only (a check)")
    b = sub.add_parser("mix")
    b.add_argument("dataset", type=Path)
    b.add_argument("npz", type=Path, nargs="+", help="pmfs outputs (their modes joined)")
    b.add_argument("prefix", help="part_calibration.py's --out (its tables' folder holds the raw ones)")
    args = ap.parse_args(argv)
    if args.what == "pmfs":
        modes = args.modes.split(",")
        pmf = mode_pmfs(args.dataset, args.parts_dir, modes, args.limit)
        io.write_npz(args.out, pmf=pmf, modes=np.array(modes))
        return 0
    mixer = Mixer(args.dataset, args.npz, Path(args.prefix).parent)
    print(f"stored PMFs against the raw W1 tables: {mixer.check():.2e} deg at most", file=sys.stderr)
    taus = mixer.choose_tau()
    tau = float(taus.loc[taus.w1.idxmin(), "tau_deg"])
    print(taus.to_string(index=False), f"\nchosen tau {tau}", file=sys.stderr)
    rows = mixer.scored(pd.read_csv(f"{args.prefix}_rows.csv"), tau)
    rows["tau_deg"] = tau
    summ = P.summary(rows, PAIRS)
    write_csv(f"{args.prefix}_mix_rows.csv", rows)
    write_csv(f"{args.prefix}_mix_taus.csv", taus)
    write_csv(f"{args.prefix}_mix_summary.csv", summ)
    print(summ.to_string(index=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
