"""Experiment (issue #18, 2026-11-24): where the adaptive labels' error comes from, and whether an
unbiased audit removes it. Not part of the workflow; run from the repository root:

    .venv/bin/python docs/experiments/label_audit.py [repeats] > results/tables/label_audit.csv

It reads the design bench's dense references (results/bench/designs/fast-2880/reference/*.npz)
and simulates nothing: every "simulation" is the reference map at that initial yaw, as the
bench's ``adaptive_emulated`` rows do. Per configuration and seeded offset:

* ``adaptive`` at budgets 40 and 64 (the study's refinement, ``sim.adaptive``), and where its
  error sits: ``hidden_mass`` is the reference mass inside intervals the refinement calls resolved
  whose outcome differs from the interpolated map (other status, or > tolerance apart), and
  ``unresolved_mass`` the mass the label bound counts;
* ``audit``: the same refinement at budget ``b1``, then ``k0`` initial yaws stratified over the
  period (one uniform draw per equal stratum), simulated and compared with the interpolated map.
  With ``p`` the fraction that differ materially, ``k = clip(c · p, k0, kmax)`` fresh stratified
  yaws are drawn, and the label is the difference estimator: the interpolated push-forward plus,
  for each audit yaw that differs, ``+1/k`` at its real outcome and ``-1/k`` at the interpolated
  one (negative bins clipped, then normalised). Unbiased for the unsmoothed histogram, whatever the
  map hides between samples; its noise is set by the mismatch rate, not by the label's spread;
* ``bands``: the same refinement at budget 40, then ``ceil(1000 · U²)`` (at most 400) initial yaws
  stratified over the unresolved stretches only (U: their share of the period), whose outcomes
  replace the half-and-half split of those stretches; the resolved intervals are interpolated;
* ``random1000``: 1,000 independent initial yaws, as the bench emulates them.

Output: one CSV row per configuration, design and repeat (sup|ΔCDF| against the reference label,
simulations used, and the diagnostics).
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from feeder.bench.designs import _load, distances, emulated_label, reference_design
from feeder.bench.reference import seed_of
from feeder.circular import circular_distance, normalize_yaw, wrap180, wrapped_gaussian_smooth
from feeder.sim.adaptive import OK, _classify, intervals
from feeder.sim.pushforward import _segment_hist, map_yaws, pushforward_pmf
from feeder.sim.simulate import run_design

REFERENCES = Path("results/bench/designs/fast-2880/reference")
ADAPTIVE = {"n0": 16, "tolerance_deg": 2.0, "min_width_deg": 0.5}  # sim.adaptive of config/config.yaml
AUDITS = {"audit_b32_k16_c2000": (32, 16, 400, 2000), "audit_b40_k24_c1500": (40, 24, 300, 1500)}
BINS, SIGMA, MIN_OK = 360, 1.0, 0.5


def material(f, s, fh, sh):
    return (s != sh) | ((s == OK) & (circular_distance(f, fh) > ADAPTIVE["tolerance_deg"]))


def where_error_sits(design, ref, period):
    """Reference mass the design gets materially wrong, inside resolved and unresolved intervals."""
    iv = intervals(design.yaws, design.final, design.status, period, design.tolerance_deg)
    bad = _classify(iv, design.min_width_deg, design.max_width_deg, design.band_gap_deg).unresolved
    beta = np.mod(ref.yaws - design.offset_deg, period) + design.offset_deg
    k = np.clip(np.searchsorted(design.yaws, beta, side="right") - 1, 0, design.yaws.size - 1)
    fh, sh = map_yaws(design, beta)
    wrong = material(ref.final, ref.status, fh, sh)
    return float((wrong & ~bad[k]).mean()), float(design.unresolved_share)


def audited(evaluate, seed, order, b1, k0, kmax, c):
    period = 360.0 / order
    design = run_design(evaluate, seed, b1, ADAPTIVE, order)
    pmf, masses = pushforward_pmf(design, BINS, 0.0)
    hist = pmf * masses.get(OK, 0.0)
    rng = np.random.default_rng(seed ^ 0x5EED)

    def audit(k):
        beta = design.offset_deg + (np.arange(k) + rng.uniform(size=k)) * period / k
        f, s = evaluate(normalize_yaw(beta))
        fh, sh = map_yaws(design, beta)
        s = np.asarray(s).astype(str)
        return np.asarray(f), s, fh, sh, material(np.asarray(f), s, fh, sh)

    f, s, fh, sh, wrong = audit(k0)
    p, used = float(wrong.mean()), k0
    k = int(min(kmax, max(k0, math.ceil(c * p))))
    if k > k0:
        f, s, fh, sh, wrong = audit(k)
        used += k
    w = 1.0 / k
    for j in np.flatnonzero(wrong):
        for sign, fin, st in ((1.0, f[j], s[j]), (-1.0, fh[j], sh[j])):
            if st == OK:
                for shift in (360.0 / order) * np.arange(order):
                    hist[int(np.floor(normalize_yaw(fin + shift))) % BINS] += sign * w / order
    hist = np.clip(hist, 0.0, None)
    label = None if hist.sum() <= 0 else wrapped_gaussian_smooth(hist / hist.sum(), SIGMA)
    return label, design.evaluations + used, p


def bands(evaluate, seed, order, b1=40, kmax=400):
    """Stratified draws over the unresolved stretches only (see the module docstring)."""
    period = 360.0 / order
    design = run_design(evaluate, seed, b1, ADAPTIVE, order)
    iv = intervals(design.yaws, design.final, design.status, period, design.tolerance_deg)
    bad = _classify(iv, design.min_width_deg, design.max_width_deg, design.band_gap_deg).unresolved
    width, shifts = iv.width[bad], period * np.arange(order)
    u = float(width.sum())
    k = int(min(kmax, math.ceil(1000.0 * (u / period) ** 2))) if u > 0 else 0
    hist = np.zeros(BINS)
    good = iv.agree & ~bad & (iv.status_a == OK)
    lo_a, delta = iv.final_a[good], wrap180(iv.final_b[good] - iv.final_a[good])
    for shift in shifts:
        lo = normalize_yaw(np.minimum(lo_a, lo_a + delta) + shift)
        hist += _segment_hist(lo, np.abs(delta), iv.width[good] / 360.0, BINS)
    if k:
        rng = np.random.default_rng(seed ^ 0xBA4D)
        pos = (np.arange(k) + rng.uniform(size=k)) * u / k
        cum = np.concatenate([[0.0], np.cumsum(width)])
        j = np.clip(np.searchsorted(cum, pos, side="right") - 1, 0, width.size - 1)
        f, s = evaluate(normalize_yaw(iv.start[bad][j] + pos - cum[j]))
        ok = np.asarray(s).astype(str) == OK
        for shift in shifts:
            hist += _segment_hist(
                normalize_yaw(np.asarray(f)[ok] + shift), np.zeros(ok.sum()), np.full(ok.sum(), u / k / 360.0), BINS
            )
    label = None if hist.sum() <= 0 else wrapped_gaussian_smooth(hist / hist.sum(), SIGMA)
    return label, design.evaluations + k


def main(repeats: int) -> pd.DataFrame:
    rows = []
    for path in sorted(REFERENCES.glob("*.npz")):
        z = _load(path)
        meta = json.loads(str(z["meta"]))
        if (z["ref_status"] == "ok").mean() < MIN_OK:
            continue
        ref = reference_design(z, ADAPTIVE["tolerance_deg"])
        ref_pmf, _ = pushforward_pmf(ref, BINS, SIGMA)
        order, key, period = round(360.0 / meta["period_deg"]), meta["entry"]["key"], meta["period_deg"]

        def evaluate(yaws, ref=ref):
            return map_yaws(ref, yaws)

        for r in range(repeats):
            base = {"config": key, "repeat": r}
            lab = emulated_label(ref, "random", 1000, seed_of(key, "random", 1000, r), BINS, SIGMA)
            rows.append(base | {"design": "random1000", "simulations": 1000, **distances(lab.pmf, ref_pmf)})
            for budget in (40, 64):
                d = run_design(evaluate, seed_of(key, "adaptive", budget, r), budget, ADAPTIVE, order)
                pmf, _ = pushforward_pmf(d, BINS, SIGMA)
                hidden, unresolved = where_error_sits(d, ref, period)
                rows.append(
                    base
                    | {"design": f"adaptive{budget}", "simulations": d.evaluations, **distances(pmf, ref_pmf)}
                    | {"hidden_mass": hidden, "unresolved_mass": unresolved}
                )
            pmf, sims = bands(evaluate, seed_of(key, "adaptive", 40, r), order)
            scores = distances(pmf, ref_pmf) if pmf is not None else {"sup_cdf": 1.0}
            rows.append(base | {"design": "bands", "simulations": sims, **scores})
            for name, (b1, k0, kmax, c) in AUDITS.items():
                pmf, sims, p = audited(evaluate, seed_of(key, "adaptive", b1, r), order, b1, k0, kmax, c)
                scores = distances(pmf, ref_pmf) if pmf is not None else {"sup_cdf": 1.0}
                rows.append(base | {"design": name, "simulations": sims, **scores, "audit_mismatch": p})
        print(key, file=sys.stderr, flush=True)
    return pd.DataFrame(rows)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 10).to_csv(sys.stdout, index=False, float_format="%.6g")
