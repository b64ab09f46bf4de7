"""Where the calibrated analytic model stops helping (stop 74): four checks, none adopted.

1. **Fences routing.** Would the calibrated analytic PMF beat the Fences specialist on the
   specialist's own validation rows (each Main fit's validation parts)? The mode of a validation
   row is chosen as the protocol chooses it (``with_calibration``: the part's other training rows),
   and also leaving the row's whole fence-type combination out (as a Fences row sees its part).
2. **A mode for an unseen part from its shape.** Per GroupKFold fold and for the locked parts: the
   held-out part's mode is the one with the least mean W1 over its K nearest training parts in
   the standardised DFT shape features (``part_raw``), if it beats the base by the margin.
3. **A learned mixture of the modes for unseen parts.** A small network maps a configuration's
   inputs (push, fence, shape features) to softmax weights over the base model and the modes,
   trained on circular W1 and early-stopped on validation parts inside each fold.
4. **A mode per configuration from its neighbours (known parts).** The mode of a Test row chosen on
   its K nearest same-type training rows instead of on all of its part's training rows.

Needs the cached mode PMFs (``results/datasets/structured_calibration.npz``) and the committed
``results/tables/structured_choices.csv`` (the specialist's validation W1):

    python docs/experiments/calibration_limits.py results/tables/calibration_limits.csv
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from feeder import io
from feeder.config import compose_config
from feeder.labels.dataset import load_dataset
from feeder.labels.metrics import circular_w1
from feeder.learn.splits import derived_seed, pick_parts
from feeder.learn.structured_calibration import _choose, calibration_settings, model_analytic, with_calibration
from feeder.learn.structured_data import fence_key, nearest_rows, structured_arrays
from feeder.learn.structured_protocol import protocol_jobs

MIX_SETTINGS = ((32, 1e-3), (8, 1e-2))  # (hidden, weight decay) of the learned mixture
KNN = (1, 3, 5, 10, 20)


def _w1(a, pmf, rows):
    return circular_w1(a["cdf"][rows], np.cumsum(pmf[rows], axis=1))


def fences_routing(a, jobs, cfg, margin) -> list[dict]:
    choices = pd.read_csv("results/tables/structured_choices.csv").set_index("fit")
    combo = np.array(["|".join(fence_key(c)[0]) for c in a["config_id"]])
    kept, w = a["kept"].astype(bool), a["mode_w1"]
    stack = np.concatenate([model_analytic(a)[:, None], a["mode_pmfs"]], axis=1)
    out = []
    for kind, key, _r, train, _scored in jobs:
        if kind != "main":
            continue
        cal = with_calibration(a, train, margin)
        frac = float(cfg.protocol.val_part_fraction)
        val_parts = pick_parts(a["part"][train], frac, derived_seed(int(cfg.seed), f"{key}:specialist"), "val")
        val = np.flatnonzero(train & kept & np.isin(a["part"], list(val_parts)))
        pool = train & kept & np.isfinite(w).all(axis=1)
        loco = np.zeros(val.size, dtype=np.int64)
        for n, i in enumerate(val):
            rows = pool & (a["part"] == a["part"][i]) & (combo != combo[i])
            if rows.any():
                loco[n] = _choose(w[rows].mean(axis=0), margin)
        scores = {
            "specialist (committed)": float(choices.loc[key, "specialist_val_cw1"]),
            "analytic": float(_w1(a, model_analytic(a), val).mean()),
            "calibrated": float(_w1(a, cal["analytic"], val).mean()),
            "calibrated, combination left out": float(
                circular_w1(a["cdf"][val], np.cumsum(stack[val, loco], axis=1)).mean()
            ),
        }
        out += [
            {"check": "fences_routing", "fit": key, "variant": k, "rows": val.size, "cw1": v} for k, v in scores.items()
        ]
    return out


def _part_means(a, mask):
    df = pd.DataFrame(a["mode_w1"][mask])
    df["part"] = a["part"][mask]
    return df.groupby("part").mean()


def shape_modes(a, data, jobs, margin) -> list[dict]:
    kept = a["kept"].astype(bool) & np.isfinite(a["mode_w1"]).all(axis=1)
    first = {p: i for i, p in reversed(list(enumerate(map(str, data["part"]))))}
    shape = {p: np.asarray(data["part_raw"])[i] for p, i in first.items()}
    out = []
    for k in KNN:
        for kind, _key, _r, train, scored in jobs:
            if kind not in ("groupkfold", "locked"):
                continue
            held = next(iter(scored.values()))
            tp, hp = _part_means(a, train & kept), _part_means(a, held & kept)
            x = np.stack([shape[p] for p in tp.index])
            mu, sd = x.mean(axis=0), x.std(axis=0)
            sd[sd == 0] = 1.0
            for p in hp.index:
                d = np.linalg.norm((x - mu) / sd - (shape[p] - mu) / sd, axis=1)
                mode = _choose(tp.to_numpy()[np.argsort(d, kind="stable")[:k]].mean(axis=0), margin)
                row = hp.loc[p].to_numpy()
                out += [
                    {"check": "shape_knn", "fit": kind, "variant": f"K={k}", "part": p, "cw1": float(row[mode])},
                    {"check": "shape_knn", "fit": kind, "variant": "base", "part": p, "cw1": float(row[0])},
                    {"check": "shape_knn", "fit": kind, "variant": "part oracle", "part": p, "cw1": float(row.min())},
                ]
    return out


def learned_mixture(a, data, jobs) -> list[dict]:
    import torch

    from feeder.learn.structured import circular_w1_loss

    torch.set_num_threads(2)
    n = len(data["part"])
    kept = a["kept"].astype(bool)[:n]
    pmfs = np.concatenate([model_analytic(a)[:, None], a["mode_pmfs"]], axis=1)[:n]
    cdf, parts = a["cdf"][:n], a["part"][:n]
    x = np.concatenate([a["x"][:n], np.asarray(data["part_raw"])], axis=1)
    p_t, c_t = torch.tensor(pmfs, dtype=torch.float32), torch.tensor(cdf, dtype=torch.float32)
    out = []
    for hidden, decay in MIX_SETTINGS:
        for kind, key, _r, train, scored in jobs:
            if kind not in ("groupkfold", "locked"):
                continue
            held = np.flatnonzero(next(iter(scored.values()))[:n] & kept)
            pool = train[:n] & kept
            val_parts = pick_parts(parts[pool], 0.2, derived_seed(0, key, "mixture"), "val")
            is_val = np.isin(parts, list(val_parts))
            fit_rows, val_rows = np.flatnonzero(pool & ~is_val), np.flatnonzero(pool & is_val)
            mu, sd = x[fit_rows].mean(axis=0), x[fit_rows].std(axis=0)
            sd[sd == 0] = 1.0
            xt = torch.tensor((x - mu) / sd, dtype=torch.float32)
            torch.manual_seed(derived_seed(0, key, "mixture", hidden))
            net = torch.nn.Sequential(
                torch.nn.Linear(x.shape[1], hidden), torch.nn.Tanh(), torch.nn.Linear(hidden, pmfs.shape[1])
            )
            with torch.no_grad():  # the untrained mixture is (almost) the base model
                net[2].weight.zero_()
                net[2].bias.zero_()
                net[2].bias[0] = 3.0
            opt = torch.optim.Adam(net.parameters(), lr=3e-3, weight_decay=decay)

            def mix(rows, net=net, xt=xt):
                return (torch.softmax(net(xt[rows]), dim=-1)[..., None] * p_t[rows]).sum(dim=1)

            best, state, bad = np.inf, None, 0
            for step in range(3000):
                opt.zero_grad()
                circular_w1_loss(mix(torch.tensor(fit_rows)), c_t[fit_rows]).backward()
                opt.step()
                if step % 20:
                    continue
                with torch.no_grad():
                    v = float(circular_w1_loss(mix(torch.tensor(val_rows)), c_t[val_rows]))
                if v < best - 1e-4:
                    best, state, bad = v, [p.detach().clone() for p in net.parameters()], 0
                elif (bad := bad + 1) > 15:
                    break
            with torch.no_grad():
                for p, s in zip(net.parameters(), state, strict=True):
                    p.copy_(s)
                got = mix(torch.tensor(held)).numpy().astype(np.float64)
            w_mix = circular_w1(cdf[held], np.cumsum(got, axis=1))
            w_base = circular_w1(cdf[held], np.cumsum(pmfs[held, 0], axis=1))
            variant = f"hidden {hidden}, decay {decay:g}"
            for i, wm, wb in zip(held, w_mix, w_base, strict=True):
                out += [
                    {"check": "learned_mixture", "fit": kind, "variant": variant, "part": parts[i], "cw1": float(wm)},
                    {
                        "check": "learned_mixture",
                        "fit": kind,
                        "variant": f"base ({variant})",
                        "part": parts[i],
                        "cw1": float(wb),
                    },
                ]
    return out


def neighbour_modes(a, jobs, margin) -> list[dict]:
    kept, w = a["kept"].astype(bool), a["mode_w1"]
    out = []
    for kind, _key, _r, train, scored in jobs:
        if kind != "main":
            continue
        cal = with_calibration(a, train, margin)
        pool = train & kept & np.isfinite(w).all(axis=1)
        rows = np.flatnonzero(scored["test"] & kept)
        picks = {"part (the protocol's)": cal["calibration_mode"][rows], "base": np.zeros(rows.size, dtype=np.int64)}
        for k in (1, 2, 3, 5):
            idx, _ = nearest_rows(a["part"], a["config_id"], pool, rows, k)
            mode = cal["calibration_mode"][rows].copy()
            for n in range(rows.size):
                nb = idx[n][idx[n] >= 0]
                if nb.size:
                    mode[n] = _choose(w[nb].mean(axis=0), margin)
            picks[f"{k} nearest same-type rows"] = mode
        for name, mode in picks.items():
            out.append(
                {
                    "check": "neighbour_modes",
                    "fit": kind,
                    "variant": name,
                    "rows": rows.size,
                    "cw1": float(w[rows, mode].mean()),
                }
            )
    return out


def summary(df: pd.DataFrame) -> pd.DataFrame:
    """Mean circular W1 per check, fit kind and variant: over rows (weighted by their count) for the
    checks scored on configurations, over parts for those scored per part."""
    per_row = df[df.part.isna()]
    per_row = per_row.groupby(["check", "variant"]).apply(lambda g: np.average(g.cw1, weights=g.rows))
    per_part = df[df.part.notna()].groupby(["check", "fit", "variant", "part"]).cw1.mean()
    per_part = per_part.groupby(["check", "fit", "variant"]).mean()
    out = pd.concat([per_row.rename("cw1").reset_index(), per_part.rename("cw1").reset_index()])
    return out.fillna({"fit": "main"})[["check", "fit", "variant", "cw1"]].round(2)


def main(argv: list[str]) -> int:
    out_csv = Path(argv[0])
    cfg = compose_config("structured", [])
    margin = calibration_settings(cfg)[1]
    data = load_dataset("results/datasets/dataset.npz")
    cache = "results/datasets/structured_candidates.npz"
    a = structured_arrays(data, cfg, "results/sim", "parts", "results/features", cache, calibration=True)
    jobs = protocol_jobs(a, cfg)[0]
    rows = fences_routing(a, jobs, cfg, margin)
    rows += shape_modes(a, data, jobs, margin)
    rows += neighbour_modes(a, jobs, margin)
    rows += learned_mixture(a, data, jobs)
    df = pd.DataFrame(rows)
    io.write_csv(out_csv, df)
    print(summary(df).to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
