"""The label convergence study: how far the PMF of the first k % of a configuration's drops is from
the PMF of all of them, and whether that distance is noise.

* :func:`js_table`: per partial level, the JS divergence to the full-run PMF against an absolute
  threshold and against a bootstrap noise floor (:func:`bootstrap_js_floor`);
* :func:`dkw_table`: per partial level, the exact sup distance of the empirical CDFs against the
  Dvoretzky-Kiefer-Wolfowitz band;
* :func:`convergence_data`: both tables and the data of Figs. 4, 5, 9 and the DKW view
  (``feeder datasets convergence`` writes them; :mod:`feeder.figures` draws them).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from feeder.labels import metrics as L
from feeder.labels.grid import PROTOCOL_SPLITS, hash_seed


def full_run_pmf(ds: dict) -> np.ndarray:
    """(N, bins) PMF of all of each configuration's drops: the 100 % level.

    For a drawn design (random, golden) it is the label itself. For a grid or adaptive design
    the label is the exact push-forward, while the drops are i.i.d. ones emulated through the
    sampled map; the paper's partial-iteration study compares a prefix with all of those drops
    (JS(P_N, P_1000)), not with the exact label, which a prefix of N drops approaches more slowly
    than it approaches its own full run. ``ds["pmf"]`` when no 100 % level was built (or no levels given)."""
    full = np.flatnonzero(np.asarray(ds.get("levels_pct", ())) == 100)
    return ds["pmf_levels"][:, int(full[0])] if full.size else ds["pmf"]


def js_by_level(ds: dict) -> np.ndarray:
    """(N, L) JS divergence in bits between each partial-level PMF and the full-run PMF
    (:func:`full_run_pmf`)."""
    return L.js_divergence(ds["pmf_levels"], full_run_pmf(ds)[:, None, :])


def bootstrap_js_floor(ds: dict, level_index: int, n_boot: int, quantile: float, seed: int, bins: int, sigma: float):
    """Noise floor of JS at one level: for every configuration draw ``n_boot`` resamples (with
    replacement) of its full-run ok yaws of the size of its ok drops at that level, smooth them
    the same way and take JS to the full PMF. Returns (floor = pooled quantile, all values)."""
    n_ok_lvl = ds["n_ok_levels"][:, level_index]
    full_pmf = full_run_pmf(ds)
    vals = []
    for i in range(len(ds["part"])):
        yaws = ds["final_yaw_deg"][i]
        hist = L.histogram(yaws[np.isfinite(yaws)], bins)
        n = int(n_ok_lvl[i])
        if n == 0:
            continue
        rng = np.random.default_rng(hash_seed(seed, "bootstrap", ds["part"][i], ds["config_id"][i], level_index))
        draws = rng.multinomial(n, hist / hist.sum(), size=n_boot).astype(np.float64)
        boot = L.wrapped_gaussian_smooth(draws, sigma)
        vals.append(L.js_divergence(boot, full_pmf[i]))
    vals = np.concatenate(vals) if vals else np.zeros(0)
    floor = float(np.quantile(vals, quantile)) if vals.size else float("nan")
    return floor, vals


def js_table(ds: dict, conv: dict, bins: int, sigma: float) -> pd.DataFrame:
    """Per partial level: JS to the full run (median, mean, SD), counts below the absolute
    threshold and below the bootstrap noise floor of that level."""
    js = js_by_level(ds)
    levels = ds["levels_pct"]
    drops = int(np.max(ds["n_drops"]))
    rows = []
    for li, k in enumerate(levels):
        floor, _ = bootstrap_js_floor(
            ds, li, int(conv["bootstrap"]), float(conv["noise_quantile"]), int(conv["seed"]), bins, sigma
        )
        col = js[:, li]
        rows.append(
            {
                "level_pct": int(k),
                "n_drops": int(drops * k // 100),
                "configurations": int(col.size),
                "median_js": float(np.median(col)),
                "mean_js": float(col.mean()),
                "sd_js": float(col.std()),
                "below_abs_threshold": int(np.sum(col < float(conv["js_threshold"]))),
                "noise_floor": floor,
                "below_noise_floor": int(np.sum(col < floor)),
            }
        )
    return pd.DataFrame(rows)


def dkw_table(ds: dict, alpha: float) -> tuple[pd.DataFrame, np.ndarray]:
    """sup|CDF_N − CDF_full| (exact empirical CDFs, no binning) for every configuration and
    partial level, against the DKW half-width ε(n) = sqrt(ln(2/α) / 2n) with n the ok drops of
    the partial run. The partial run is a prefix of the full run, so for exchangeable drops the
    distance is at most the distance to the true CDF and ≥ 1 − α of configurations should lie
    inside the band; fewer means the drop sequence is not yet representative at that N."""
    levels = ds["levels_pct"]
    n_rows = len(ds["part"])
    sup = np.full((n_rows, levels.size), np.nan)
    for i in range(n_rows):
        y = ds["final_yaw_deg"][i, : int(ds["n_drops"][i])]
        full = y[np.isfinite(y)]
        counts = L.level_drop_counts(y.size, levels)
        for li, c in enumerate(counts):
            part = y[:c]
            part = part[np.isfinite(part)]
            if part.size:
                sup[i, li] = L.ecdf_sup_distance(part, full)
    n_ok = ds["n_ok_levels"]
    eps = L.dkw_epsilon(np.maximum(n_ok, 1), alpha)
    inside = np.where(np.isfinite(sup), sup <= eps, False)
    drops = int(np.max(ds["n_drops"]))
    rows = []
    for li, k in enumerate(levels):
        s = sup[:, li]
        s = s[np.isfinite(s)]
        rows.append(
            {
                "level_pct": int(k),
                "n_drops": int(drops * k // 100),
                "configurations": int(s.size),
                "median_n_ok": float(np.median(n_ok[:, li])),
                "dkw_epsilon_at_n_drops": float(L.dkw_epsilon(max(drops * k // 100, 1), alpha)),
                "median_sup": float(np.median(s)) if s.size else float("nan"),
                "q90_sup": float(np.quantile(s, 0.9)) if s.size else float("nan"),
                "fraction_inside_band": float(inside[:, li].mean()),
            }
        )
    return pd.DataFrame(rows), sup


def pick_examples(pmf: np.ndarray, prominence_frac: float) -> list[tuple[int, str]]:
    """Rows whose PMFs show different shapes: the median-entropy row with one, two and three or
    more peaks (peaks with prominence ≥ prominence_frac · max, found on the circle), plus the
    most concentrated and the most spread-out PMF."""
    from scipy.signal import find_peaks

    ent = -(np.where(pmf > 0, pmf * np.log2(np.where(pmf > 0, pmf, 1)), 0)).sum(axis=1)
    n_peaks = np.empty(len(pmf), dtype=np.int64)
    bins = pmf.shape[1]
    for i, p in enumerate(pmf):
        tripled = np.concatenate([p, p, p])
        pk, _ = find_peaks(tripled, prominence=prominence_frac * p.max())
        n_peaks[i] = int(np.sum((pk >= bins) & (pk < 2 * bins)))
    picks: list[tuple[int, str]] = []
    for label, sel in (("1 peak", n_peaks == 1), ("2 peaks", n_peaks == 2), ("3+ peaks", n_peaks >= 3)):
        idx = np.flatnonzero(sel)
        if idx.size:
            picks.append((int(idx[np.argsort(ent[idx])[idx.size // 2]]), label))
    for i, label in ((int(np.argmin(ent)), "most concentrated"), (int(np.argmax(ent)), "most spread")):
        if i not in [j for j, _ in picks]:
            picks.append((i, label))
    return picks


CONVERGENCE_KEYS = ("part", "config_id", "pmf", "pmf_levels", "final_yaw_deg", "n_drops", "n_ok_levels")


def protocol_rows(ds: dict) -> dict:
    """The dataset's rows of the paper's protocol (Main, Fences, Parts: not the wide library), with
    the keys the convergence study reads."""
    keep = np.isin(ds["split"], PROTOCOL_SPLITS)
    out = {k: ds[k][keep] for k in CONVERGENCE_KEYS}
    out["levels_pct"] = ds["levels_pct"]
    return out


def convergence_data(ds: dict, settings: dict) -> dict:
    """Everything the convergence study shows: the two tables (``dkw_table``, ``js_table``) and the
    data of Figs. 4, 5, 9 and the DKW view (``fig4``, ``fig5``, ``fig9``, ``dkw``: the formats the
    modules of the same names in :mod:`feeder.figures` read; all drawing is there). Over the rows
    of the paper's protocol only (:func:`protocol_rows`), when the dataset has splits."""
    if "split" in ds:
        ds = protocol_rows(ds)
    conv = settings["datasets"]["convergence"]
    bins = int(settings["labels"]["bins"])
    sigma = float(settings["labels"]["sigma_bins"])
    levels = ds["levels_pct"]
    drops = int(np.max(ds["n_drops"]))
    n_axis = drops * levels // 100
    js = js_by_level(ds)

    # Fig. 4: JS(P_N || P_full) vs N, mean ± SD over random configurations
    rng = np.random.default_rng(hash_seed(conv["seed"], "fig4"))
    pick = rng.choice(len(js), size=min(int(conv["fig4_configurations"]), len(js)), replace=False)
    sub = js[np.sort(pick)]
    fig4 = pd.DataFrame(
        {
            "level_pct": levels.astype(np.int64),
            "n_drops": n_axis.astype(np.int64),
            "mean_js": sub.mean(axis=0),
            "sd_js": sub.std(axis=0),
            "configurations": len(pick),
        }
    )

    # Fig. 5: JS at the comparison level with the bootstrap noise floor
    li = int(np.argmin(np.abs(levels - int(conv["compare_pct"]))))
    jst = js_table(ds, conv, bins, sigma)
    fig5 = {
        "js": js[:, li],
        "noise_floor": np.float64(jst["noise_floor"].iloc[li]),
        "noise_quantile": np.float64(conv["noise_quantile"]),
        "n_drops": np.int64(n_axis[li]),
        "n_drops_full": np.int64(drops),
    }

    # Fig. 9: example PMFs of different shapes
    picks = pick_examples(ds["pmf"], float(conv["peak_prominence"]))
    rows = [i for i, _ in picks]
    fig9 = {
        "part": np.asarray(ds["part"])[rows].astype(str),
        "config_id": np.asarray(ds["config_id"])[rows].astype(str),
        "label": np.array([label for _, label in picks]),
        "pmf": ds["pmf"][rows],
        "yaw_deg": (np.arange(bins) + 0.5) * 360.0 / bins,
    }

    # DKW convergence view: quantiles over configurations of the sup distance per level
    alpha = float(conv["dkw_alpha"])
    table, sup = dkw_table(ds, alpha)
    ok = np.isfinite(sup)

    def per_level(q):
        return np.array([np.quantile(sup[ok[:, j], j], q) if ok[:, j].any() else np.nan for j in range(levels.size)])

    dkw = {
        "level_pct": levels.astype(np.int64),
        "n_drops": n_axis.astype(np.int64),
        "q10_sup": per_level(0.1),
        "median_sup": per_level(0.5),
        "q90_sup": per_level(0.9),
        "dkw_epsilon": L.dkw_epsilon(np.maximum(n_axis, 1), alpha),
        "fraction_inside_band": table["fraction_inside_band"].to_numpy(),
        "alpha": np.float64(alpha),
        "n_drops_full": np.int64(drops),
    }
    return {"dkw_table": table, "js_table": jst, "fig4": fig4, "fig5": fig5, "fig9": fig9, "dkw": dkw}
