"""The structured predictor's answer blended with its fallback (issue #39, stop 74).

A fit scored on known parts answers ``λ · network + (1 − λ) · fallback``, with ``λ`` of
``blend.weights`` (``config/hydra/structured.yaml``) chosen on the fit's validation rows by the
least mean circular W1 of the seeds' mean PMF (ties: the larger weight, the network). The fallback
reads no network:

* for a network that reads the part's labels of the query's own fence-type combination, the
  **gated neighbour**: the label of the part's nearest labelled configuration of those fence types
  when it lies within the gate (``neighbour.gates_deg``, the gate chosen on the training rows, each
  from its nearest other one), else the analytic PMF;
* for the Fences specialist (no label of the query's combination), the analytic PMF.

The analytic PMF is each part's calibrated one where the fit calibrates
(:mod:`feeder.learn.structured_calibration`). Circular W1 is convex in the prediction, so a blend
scores at most the blend of the two scores; ``blend.weights: [1.0]`` is the network alone.

With ``blend.by_fallback`` (stop 76) the weight is chosen twice on the same validation rows: once
on the rows whose fallback is a neighbour's label (``weight``) and once on those whose fallback is
the analytic PMF (``analytic_weight``). A row answers with the weight of its own fallback kind. A
kind without validation rows takes the weight chosen on all of them.
"""

from __future__ import annotations

import numpy as np

from feeder.errors import FeederError


def blend_weights(cfg) -> list[float]:
    """``blend.weights`` (``[1.0]``, the network alone, when absent) checked: a one-line FeederError
    unless it is a non-empty list of numbers in [0, 1]."""
    section = cfg.get("blend") or {}
    weights = list(section.get("weights", [1.0]))
    ok = bool(weights) and all(
        isinstance(w, (int, float)) and not isinstance(w, bool) and 0.0 <= float(w) <= 1.0 for w in weights
    )
    if not ok:
        raise FeederError(f"blend.weights must be a non-empty list of numbers in [0, 1], got {weights!r}")
    return [float(w) for w in weights]


def by_fallback(cfg) -> bool:
    """``blend.by_fallback`` (false when absent) checked: a one-line FeederError unless a bool."""
    value = (cfg.get("blend") or {}).get("by_fallback", False)
    if not isinstance(value, bool):
        raise FeederError(f"blend.by_fallback must be true or false, got {value!r}")
    return value


def blended(network_pmf, fallback_pmf, weight) -> np.ndarray:
    """``weight · network_pmf + (1 − weight) · fallback_pmf`` (rows of PMFs; ``weight`` one number
    or one per row)."""
    w = np.asarray(weight, np.float64)
    if w.ndim == 1:
        w = w[:, None]
    return w * np.asarray(network_pmf, np.float64) + (1.0 - w) * np.asarray(fallback_pmf, np.float64)


def analytic_weight(blend: dict) -> float:
    """The weight of a :func:`fit_blend` (or its shipped meta) for the rows whose fallback is the
    analytic PMF: ``analytic_weight``, or ``weight`` in a file written before ``blend.by_fallback``."""
    return float(blend.get("analytic_weight", blend["weight"]))


def row_weights(blend: dict, from_label) -> np.ndarray:
    """Each row's weight of a :func:`fit_blend` (or its shipped meta): ``weight`` where the row's
    fallback is a neighbour's label (``from_label``), else :func:`analytic_weight`."""
    return np.where(np.asarray(from_label, dtype=bool), float(blend["weight"]), analytic_weight(blend))


def blends_anything(blend: dict | None) -> bool:
    """Whether a blend moves any answer off the network's (some weight below 1)."""
    return blend is not None and (float(blend["weight"]) != 1.0 or analytic_weight(blend) != 1.0)


def choose_weight(cdf, network_pmf, fallback_pmf, weights) -> tuple[float, dict[float, float]]:
    """The weight of ``weights`` whose blend scores the least mean circular W1 against the label
    CDFs ``cdf`` (ties: the larger weight), and every weight's score. One weight: that one (no rows
    needed); several and no rows: a one-line FeederError."""
    from feeder.labels.metrics import circular_w1

    weights = [float(w) for w in weights]
    if len(weights) == 1:
        return weights[0], {}
    cdf = np.asarray(cdf, np.float64)
    if cdf.shape[0] == 0:
        raise FeederError("the blend's weight is chosen on validation rows, and the fit has none")
    scores = {
        w: float(circular_w1(cdf, np.cumsum(blended(network_pmf, fallback_pmf, w), axis=1)).mean()) for w in weights
    }
    best = min(scores, key=lambda w: (scores[w], -w))
    return best, scores


def fit_gate(arrays: dict, train, gates) -> float:
    """The gate of ``gates`` (degrees) chosen on the kept ``train`` rows of ``arrays``
    (:func:`feeder.learn.neighbour.choose_gate`, each row from its nearest other one)."""
    from feeder.learn.neighbour import choose_gate
    from feeder.learn.structured_data import neighbour_source

    pool = np.asarray(train, dtype=bool) & np.asarray(arrays["kept"], dtype=bool)
    source, source_pool = neighbour_source(arrays, pool)  # with the mirrored labels (model.mirror_labels)
    gates = [float(g) for g in gates]
    scored = np.flatnonzero(pool)  # the training rows, each from its nearest other (mirrored or not)
    return float(
        choose_gate(source["pmf"], source["analytic"], source["part"], source["config_id"], source_pool, gates, scored)
    )


def gated_pmfs(arrays: dict, pool, rows, gate_deg: float) -> np.ndarray:
    """(len(rows), bins): for each of ``rows`` the label of the nearest kept ``pool`` row of the
    same part and fence types (never itself) within ``gate_deg`` (``|Δθ1| + |Δθ2|``), else its
    ``analytic`` PMF. The pool holds the mirrored labels too
    (:func:`feeder.learn.structured_data.neighbour_source`)."""
    return gated_choice(arrays, pool, rows, gate_deg)[0]


def gated_choice(arrays: dict, pool, rows, gate_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`gated_pmfs` and, per row, whether its answer is a neighbour's label (else the
    analytic PMF)."""
    from feeder.learn.neighbour import angle_distance, neighbour_index
    from feeder.learn.structured_data import neighbour_source

    source, pool = neighbour_source(arrays, pool)
    rows = np.asarray(rows, dtype=np.int64)
    cids = source["config_id"]
    idx = neighbour_index(source["part"], cids, pool, rows)
    out = np.asarray(arrays["analytic"])[rows].copy()
    from_label = np.zeros(rows.size, dtype=bool)
    for n, (i, j) in enumerate(zip(rows, idx, strict=True)):
        if j >= 0 and angle_distance(cids[i], cids[j]) <= gate_deg:
            out[n], from_label[n] = source["pmf"][j], True
    return out, from_label


def fallback_choice(arrays: dict, pool, rows, gate_deg: float | None) -> tuple[np.ndarray, np.ndarray]:
    """The blend's fallback of ``rows`` (module doc): :func:`gated_pmfs` from ``pool`` with
    ``gate_deg``, or the ``analytic`` PMF when ``gate_deg`` is None (the specialist's); and per row
    whether its fallback is a neighbour's label."""
    rows = np.asarray(rows, dtype=np.int64)
    if gate_deg is None:
        return np.asarray(arrays["analytic"])[rows].copy(), np.zeros(rows.size, dtype=bool)
    return gated_choice(arrays, pool, rows, gate_deg)


def fit_blend(fitted: dict, arrays: dict, cfg, train, own_labels: bool) -> dict:
    """The blend of a fit of :func:`feeder.learn.structured_protocol.fit_protocol` on ``arrays``
    (training rows ``train``): ``{"weight", "analytic_weight", "gate_deg", "scores"}`` (with
    ``blend.by_fallback`` also each kind's ``*_rows`` and ``*_scores`` and the split blend's
    ``split_cw1``), the weights chosen on the fit's validation rows from the early-stopped seeds
    (their validation inputs; each validation row's fallback from its own part's other validation
    rows, as its network inputs). ``own_labels``: the network reads labels of the
    query's own type combination (the gated neighbour is its fallback), else the analytic PMF is
    (the specialist's). Without ``blend.by_fallback`` both weights are the one chosen on all rows;
    with it, each is chosen on the rows of its fallback kind (module doc)."""
    from feeder.learn.structured import predict

    weights = blend_weights(cfg)
    gate = fit_gate(arrays, train, cfg.neighbour.gates_deg) if own_labels else None
    if len(weights) == 1:
        return {"weight": weights[0], "analytic_weight": weights[0], "gate_deg": gate, "scores": {}}
    early, rows = fitted["early"], fitted["val_rows"]
    net = np.mean([predict(f, fitted["val_inputs"], rows, early["mean_pmf"])[0] for f in early["fits"]], axis=0)
    fallback, from_label = fallback_choice(arrays, fitted["val_pool"], rows, gate)
    cdf = arrays["cdf"][rows]
    weight, scores = choose_weight(cdf, net, fallback, weights)
    out = {"weight": weight, "analytic_weight": weight, "gate_deg": gate, "scores": scores}
    if not by_fallback(cfg):
        return out
    from feeder.labels.metrics import circular_w1

    for kind, mine in (("label", from_label), ("analytic", ~from_label)):
        out[f"{kind}_rows"] = int(mine.sum())
        if mine.any():
            w, s = choose_weight(cdf[mine], net[mine], fallback[mine], weights)
            out["weight" if kind == "label" else "analytic_weight"], out[f"{kind}_scores"] = w, s
    split = blended(net, fallback, row_weights(out, from_label))
    out["split_cw1"] = float(circular_w1(cdf, np.cumsum(split, axis=1)).mean())
    return out


def blend_choice(blend: dict) -> dict:
    """The choice table's entries of a :func:`fit_blend`: the weights, the gate (NaN: none) and the
    network's and the chosen blend's validation circular W1 (NaN with one weight; with
    ``blend.by_fallback`` the blend's is that of each row at its own kind's weight)."""
    scores = blend["scores"]
    kinds = {f"blend_{k}_rows": int(blend[f"{k}_rows"]) for k in ("label", "analytic") if f"{k}_rows" in blend}
    return {
        **kinds,
        "blend_weight": float(blend["weight"]),
        "blend_analytic_weight": analytic_weight(blend),
        "blend_gate_deg": float("nan") if blend["gate_deg"] is None else float(blend["gate_deg"]),
        "blend_val_cw1": blend.get("split_cw1", scores.get(blend["weight"], float("nan"))),
        "blend_network_val_cw1": scores.get(1.0, float("nan")),
    }
