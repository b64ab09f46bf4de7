"""The structured predictor as shipped (issue #39, item 5): trained once on every configuration of
the study, answering for a part the study has labelled at a configuration it did not simulate.

    feeder fit-structured --dataset results/datasets/dataset.npz --sim-dir results/sim \\
        --parts-dir parts --features-dir results/features --out results/models/structured.npz [overrides]

trains it under the protocol's fit (:func:`feeder.learn.structured_protocol.fit_protocol`: validation
parts, the search and the seeds, all from ``config/hydra/structured.yaml``) on every configuration
(no part locked away: the protocol's tables already report it) and writes one ``.npz``: each seed's
network state, the input scaling, the training-mean PMF, each part's label frame and the settings.
``feeder export-study --structured`` puts it into ``models/study``, where
:class:`feeder.learn.study.StudyModel` answers with it (docs/structured.md).

At an answer (:meth:`ShippedStructured.answer`, numpy only) the query's candidates and push inputs
come from the part's outline (:func:`feeder.learn.structured_data.configuration_inputs`, about a
third of a second a configuration), its neighbour inputs from the part's labelled configurations
(:func:`feeder.learn.structured_data.neighbour_block`, with every labelled configuration of the
part as the pool, as for a scored row of the protocol), and the PMF is the mean of the seeds' PMFs
(circular W1 is convex, so the mean scores no worse than the seeds' mean score).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import sys
from dataclasses import asdict
from pathlib import Path

import numpy as np

from feeder.errors import FeederError

SHIPPED_FORMAT = 1  # version of the layout of the file
SHIPPED_FILE = "structured.npz"  # its name in models/study
SHIPPED_KEY = "shipped"  # the fit id its validation parts and seeds derive from
PROGRESS_EVERY = 50  # configurations between progress messages of an answer


def scene_digest(scene: dict) -> str:
    """SHA-256 (hex) of a scene as canonical JSON (sorted keys): two scenes that differ in any
    value differ here (how the study and this file know the scene they were made in)."""
    return hashlib.sha256(json.dumps(scene, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


SPECIALIST = "specialist/"  # the prefix of the Fences specialist's arrays (model.fences_specialist)


def state_arrays(fits, prefix: str = "") -> dict[str, np.ndarray]:
    """Each fitted seed's PMF network state as float64 arrays named ``<prefix>seed<i>/<parameter>``."""
    out = {}
    for i, f in enumerate(fits):
        for name, value in f.net.state_dict().items():
            out[f"{prefix}seed{i}/{name}"] = value.detach().cpu().numpy().astype(np.float64)
    return out


def fit_shipped(arrays: dict, cfg, data: dict, train=None) -> dict:
    """The arrays of the shipped file: the protocol's fit on the configurations ``train`` (a boolean
    mask; default: every one) of ``arrays`` (:func:`feeder.learn.structured_data.structured_arrays`
    of the dataset ``data``, whose settings give the label frame, bins, scene and units), in
    :func:`shipped_arrays`, keeping the neighbour inputs (each label's analytic miss) of ``train``
    rows only: no other row's label is in the file."""
    from feeder.learn.structured_blend import fit_blend
    from feeder.learn.structured_protocol import cross_only, drop_count, fences_specialist, fit_protocol, specialist_cfg
    from feeder.mechanics.fence import default_scene

    if drop_count(cfg, "neighbour_basins") or drop_count(cfg, "neighbour_candidates"):
        raise FeederError(
            "fit-structured ships whole-label neighbours only (model.neighbour_basins and neighbour_candidates: 0)"
        )
    if drop_count(cfg):
        raise FeederError("fit-structured ships a predictor that simulates nothing (model.drops: 0)")
    if cross_only(cfg):
        raise FeederError(
            "fit-structured ships a predictor that reads every label of the part (model.cross_only: false)"
        )
    train = np.ones(len(arrays["part"]), dtype=bool) if train is None else np.asarray(train, dtype=bool)
    settings = json.loads(str(data["settings"]))
    labels = settings["labels"]
    arrays = calibrated_arrays(arrays, train, cfg)
    fitted = fit_protocol(arrays, train, cfg, SHIPPED_KEY, known=True)
    fitted["blend"] = fit_blend(fitted, arrays, cfg, train, own_labels=True)  # blend.weights, as a Main fit
    specialist = None
    if fences_specialist(cfg):  # answers the configurations with no label of their own type combination
        specialist = fit_protocol(arrays, train, specialist_cfg(cfg), f"{SHIPPED_KEY}:specialist", known=True)
        specialist["blend"] = fit_blend(specialist, arrays, specialist_cfg(cfg), train, own_labels=False)
    out = shipped_arrays(
        fitted,
        arrays,
        cfg,
        str(data["label_frame"]),
        int(labels["bins"]),
        float(labels["sigma_bins"]),
        settings.get("scene") or default_scene(),
        str((settings.get("parts") or {}).get("units", "auto")),
        specialist,
    )
    labelled = {(str(p), str(c)) for p, c in zip(arrays["part"][train], arrays["config_id"][train], strict=True)}
    mine = [(str(p), str(c)) in labelled for p, c in zip(out["miss_part"], out["miss_config_id"], strict=True)]
    mine = np.asarray(mine, dtype=bool)
    return out | {k: out[k][mine] for k in ("miss_part", "miss_config_id", "miss")}


def calibrated_arrays(arrays: dict, train, cfg) -> dict:
    """``arrays`` with each row's analytic PMF calibrated on its part's labelled ``train`` rows
    (:func:`feeder.learn.structured_calibration.with_calibration`) when ``calibration.network`` is on,
    as the protocol's Main fits; unchanged otherwise. A one-line FeederError when it is on and
    ``arrays`` lack the modes' PMFs (:func:`~feeder.learn.structured_data.structured_arrays` with
    ``calibration``)."""
    from feeder.learn.structured_calibration import calibration_network, calibration_settings, with_calibration

    if not calibration_network(cfg):
        return arrays
    modes, margin = calibration_settings(cfg)
    if not modes:
        raise FeederError("calibration.network: true needs calibration.modes")
    if "mode_pmfs" not in arrays:
        raise FeederError("calibration.network: true needs the modes' PMFs (structured_arrays with calibration)")
    return with_calibration(arrays, train, margin)


def calibration_meta(fitted: dict, arrays: dict, cfg) -> dict | None:
    """What an answer needs to calibrate a known part's analytic PMF as the fit did: the modes (their
    :meth:`~feeder.mechanics.candidates.Variant.spec`) and each trained part's mode chosen on all its
    labelled training rows (:func:`~feeder.learn.structured_calibration.part_modes`; ``base`` where
    none beats the model); None when the fit did not calibrate."""
    from feeder.learn.structured_calibration import calibration_settings, part_modes

    if "calibration_mode" not in arrays:
        return None
    modes, margin = calibration_settings(cfg)
    names = ["base"] + [m.name for m in modes]
    pool = np.asarray(fitted["train"], dtype=bool) & np.asarray(arrays["kept"], dtype=bool)
    chosen = part_modes(arrays["mode_w1"], arrays["part"], pool, margin)
    return {
        "margin_deg": margin,
        "modes": [m.spec() for m in modes],
        "part_modes": {part: names[m] for part, m in sorted(chosen.items())},
    }


def shipped_arrays(
    fitted: dict,
    arrays: dict,
    cfg,
    label_frame: str,
    bins: int,
    sigma_bins: float,
    scene: dict,
    units: str = "auto",
    specialist: dict | None = None,
):
    """The shipped file's arrays of a fit of :func:`feeder.learn.structured_protocol.fit_protocol`
    on ``arrays``: ``meta`` (JSON: the settings an answer needs and the choice made), the input
    scaling, the training-mean PMF, each part's label frame and each seed's network state; with a
    ``specialist`` fit (``model.fences_specialist``) its settings, choice, scaling, mean PMF and
    states too, under :data:`SPECIALIST`."""
    from omegaconf import OmegaConf

    from feeder.learn.structured_data import candidate_settings, label_miss, model_analytic
    from feeder.learn.structured_protocol import composed_on, neighbour_count, neighbour_signed

    parts, first = np.unique(arrays["part"], return_index=True)
    kept = np.asarray(arrays["kept"], dtype=bool)
    meta = {
        "format": SHIPPED_FORMAT,
        "net": asdict(fitted["settings"]),
        "n_variants": int(arrays["masses"].shape[2]),
        "seeds": len(fitted["fits"]),
        "neighbours": neighbour_count(cfg),
        "cross_neighbours": neighbour_count(cfg, "cross_neighbours"),
        "neighbour_near_deg": float(cfg.model.neighbour_near_deg),
        "composed": composed_on(cfg),
        "wide_sigma_bins": float(cfg.model.wide_sigma_bins),
        "variants": OmegaConf.to_container(cfg.candidates.variants, resolve=True),
        "candidates": candidate_settings(cfg.candidates, bins, sigma_bins),
        "bins": int(bins),
        "sigma_bins": float(sigma_bins),
        "label_frame": str(label_frame),
        "scene_sha256": scene_digest(scene),
        "units": str(units),  # how the parts' STLs were read (parts.units)
        "choice": fitted["choice"],
    }
    calibration = calibration_meta(fitted, arrays, cfg)
    if calibration is not None:  # calibration.network: each known part's mode
        meta["calibration"] = calibration
    if "blend" in fitted:  # blend.weights (fit_shipped): the answer blended with its fallback
        meta["blend"] = blend_meta(fitted["blend"])
    if neighbour_signed(cfg):  # the neighbours' signed angle steps are inputs (a file without the key: not)
        meta["neighbour_signed"] = True
    extra = {}
    if "mirror_deg" in arrays:  # model.mirror_labels: each part's mirror constant (NaN: no mirror axis)
        meta["mirror_labels"] = True
        extra["mirror_deg"] = np.asarray(arrays["mirror_deg"], dtype=np.float64)[first]
    if specialist is not None:
        meta["specialist"] = {
            "net": asdict(specialist["settings"]),
            "seeds": len(specialist["fits"]),
            "choice": specialist["choice"],
        }
        if "blend" in specialist:
            meta["specialist"]["blend"] = blend_meta(specialist["blend"])
        extra |= {
            f"{SPECIALIST}x_mean": specialist["x_mean"],
            f"{SPECIALIST}x_sd": specialist["x_sd"],
            f"{SPECIALIST}mean_pmf": specialist["mean_pmf"],
            **state_arrays(specialist["fits"], SPECIALIST),
        }
    return {
        "meta": np.array(json.dumps(meta, sort_keys=True)),
        "x_mean": fitted["x_mean"],
        "x_sd": fitted["x_sd"],
        "mean_pmf": fitted["mean_pmf"],
        "part_ids": parts,
        "frame_deg": np.asarray(arrays["frame_deg"], dtype=np.float64)[first],
        # each labelled configuration's label against its analytic PMF: a neighbour input, kept so that an
        # answer computes the analytic PMFs of its few neighbours only
        "miss_part": np.asarray(arrays["part"])[kept],
        "miss_config_id": np.asarray(arrays["config_id"])[kept],
        "miss": label_miss(arrays["pmf"][kept], model_analytic(arrays)[kept]),
        **state_arrays(fitted["fits"]),
        **extra,
    }


def blend_meta(blend: dict) -> dict:
    """What an answer needs of a :func:`feeder.learn.structured_blend.fit_blend`: the weight, the
    gate (None: the fallback is the analytic PMF) and the validation scores it was chosen on."""
    from feeder.learn.structured_blend import analytic_weight

    out = {
        "weight": float(blend["weight"]),
        "analytic_weight": analytic_weight(blend),
        "gate_deg": None if blend["gate_deg"] is None else float(blend["gate_deg"]),
        "val_cw1": {str(w): float(v) for w, v in blend["scores"].items()},
    }
    for kind in ("label", "analytic"):  # blend.by_fallback: each fallback kind's own choice
        if f"{kind}_scores" in blend:
            out[f"{kind}_val_cw1"] = {str(w): float(v) for w, v in blend[f"{kind}_scores"].items()}
            out[f"{kind}_rows"] = int(blend[f"{kind}_rows"])
    if "split_cw1" in blend:
        out["split_val_cw1"] = float(blend["split_cw1"])
    return out


class ShippedStructured:
    """The shipped file, answering in numpy (:meth:`answer`)."""

    def __init__(self, arrays: dict):

        self.meta = json.loads(str(arrays["meta"]))
        if self.meta.get("format") != SHIPPED_FORMAT:
            raise FeederError(
                f"the structured predictor's file has format {self.meta.get('format')!r}, this code reads "
                f"{SHIPPED_FORMAT}: run feeder fit-structured and feeder export-study again"
            )
        self.networks = {"default": self._network(arrays, "", self.meta)}
        if "specialist" in self.meta:  # model.fences_specialist: for a query with no label of its own combination
            self.networks["specialist"] = self._network(arrays, SPECIALIST, self.meta["specialist"])
        self.frames = {str(p): float(f) for p, f in zip(arrays["part_ids"], arrays["frame_deg"], strict=True)}
        # model.mirror_labels: each known part's mirror constant (structured_mirror; NaN: no mirror axis)
        self.mirrors = (
            {str(p): float(c) for p, c in zip(arrays["part_ids"], arrays["mirror_deg"], strict=True)}
            if self.meta.get("mirror_labels")
            else {}
        )
        self.miss = {
            (str(p), str(c)): float(m)
            for p, c, m in zip(arrays["miss_part"], arrays["miss_config_id"], arrays["miss"], strict=True)
        }

    @staticmethod
    def _network(arrays: dict, prefix: str, meta: dict) -> dict:
        """One network of the file: its settings, input scaling, training-mean PMF and seeds' states."""
        from feeder.learn.structured import NetSettings

        seeds = [f"{prefix}seed{i}/" for i in range(int(meta["seeds"]))]
        return {
            "blend": meta.get("blend"),  # None: the network alone
            "settings": NetSettings(**meta["net"]),
            "x_mean": arrays[f"{prefix}x_mean"],
            "x_sd": arrays[f"{prefix}x_sd"],
            "mean_pmf": arrays[f"{prefix}mean_pmf"],
            "params": [{k[len(s) :]: arrays[k] for k in arrays if k.startswith(s)} for s in seeds],
        }

    @classmethod
    def load(cls, path) -> ShippedStructured:
        """The file at ``path``; a one-line FeederError when it is not one."""
        import zipfile

        try:
            with np.load(path, allow_pickle=False) as z:
                return cls({k: z[k] for k in z.files})
        except (OSError, ValueError, KeyError, TypeError, zipfile.BadZipFile, json.JSONDecodeError) as err:
            raise FeederError(
                f"{path} is not a structured predictor's file ({type(err).__name__}): run feeder fit-structured "
                "and feeder export-study again, or delete it (the study then answers with its nearest labels)"
            ) from None

    def part_mode(self, part: str):
        """The :class:`~feeder.mechanics.candidates.Variant` calibrated for a trained ``part``
        (``calibration.network``), or None: the analytic model's own PMF."""
        from feeder.mechanics.candidates import variants_from_config

        calibration = self.meta.get("calibration")
        name = None if calibration is None else calibration["part_modes"].get(str(part), "base")
        if name in (None, "base"):
            return None
        return {v.name: v for v in variants_from_config(calibration["modes"])}[name]

    @property
    def units(self) -> str:
        """How the parts' STLs were read in training (``parts.units``)."""
        return str(self.meta.get("units", "auto"))

    @property
    def composes(self) -> bool:
        """Whether it reads the part's one-fence drop maps composed (trained with ``model.composed``)."""
        return bool(self.meta.get("composed"))

    def knows(self, part: str) -> bool:
        """Whether it was trained with the library part ``part``."""
        return str(part) in self.frames

    @property
    def bins(self) -> int:
        return int(self.meta["bins"])

    def serves(self, bins: int, sigma_bins: float, scene_sha256: str) -> bool:
        """Whether it answers for labels of ``bins`` and ``sigma_bins`` in the scene of that digest."""
        m = self.meta
        return int(bins) == m["bins"] and float(sigma_bins) == m["sigma_bins"] and scene_sha256 == m["scene_sha256"]

    def frame_of(self, part: str) -> float:
        """The part's label frame (degrees; 0 for ``part``-frame labels)."""
        if part not in self.frames:
            raise FeederError(f"the structured predictor was not trained with part {part}")
        return self.frames[part] if self.meta["label_frame"] == "principal" else 0.0

    def mirror_deg(self, part: str) -> float:
        """The known ``part``'s mirror constant (:func:`feeder.learn.structured_mirror.label_mirror_deg`),
        NaN when it has no mirror axis or the file was trained without ``model.mirror_labels``."""
        return self.mirrors.get(str(part), math.nan)

    def mirrored_ids(self, part: str, pool_ids) -> list[tuple[str, int]]:
        """(configuration, position in ``pool_ids``) of every one-fence label of ``pool_ids`` read at
        the other location (:func:`feeder.learn.structured_mirror.mirror_config_id`); none when
        :meth:`mirror_deg` is NaN."""
        from feeder.learn.structured_mirror import mirror_config_id

        if not math.isfinite(self.mirror_deg(part)):
            return []
        pairs = [(mirror_config_id(c), n) for n, c in enumerate(pool_ids)]
        return [(c, n) for c, n in pairs if c is not None]

    def has_neighbour(self, config_id: str, pool_ids) -> bool:
        """Whether ``config_id`` has a neighbour among the part's labelled ``pool_ids`` (same fence
        types, the same downstream fence type when cross neighbours are used, or each of its two fences
        alone when it composes)."""
        from feeder.learn.structured_data import fence_alone, fence_key

        (t1, t2), _ = fence_key(config_id)
        alone = set()  # (location, type) of the part's one-fence configurations
        for other in pool_ids:
            (o1, o2), _ = fence_key(other)
            if self.meta["neighbours"] > 0 and (o1, o2) == (t1, t2):
                return True
            if self.meta["cross_neighbours"] > 0 and t1 != "none" and o1 == t1 and (o1, o2) != (t1, t2):
                return True
            alone.add(fence_alone(other))
        return self.composes and "none" not in (t1, t2) and {(1, t1), (2, t2)} <= alone

    def answer(
        self, geom, part: str, config_ids, pool_ids, pool_pmf, pool_ok, scene: dict, progress=None, pool_maps=None
    ) -> np.ndarray:
        """(len(config_ids), bins) PMFs in the label frame of ``part`` (push geometry ``geom``) at
        ``config_ids``, from its labelled configurations ``pool_ids`` with their labels ``pool_pmf``
        (label frame) and ok shares ``pool_ok``. ``progress(message)`` hears of every
        :data:`PROGRESS_EVERY` configurations' candidates. A predictor trained with
        ``model.composed`` also reads ``pool_maps``: the sampled drop maps (part frame) of the
        pool's one-fence configurations by their index in ``pool_ids``."""
        from feeder.lane.fences import parse_config_id
        from feeder.learn.structured import batch_inputs, diffuse_components, forward_numpy
        from feeder.learn.structured_blend import blended, blends_anything, row_weights
        from feeder.learn.structured_data import (
            composed_block,
            configuration_inputs,
            label_miss,
            neighbour_block,
            neighbour_rows,
            row_inputs,
        )
        from feeder.learn.structured_mirror import with_mirrors
        from feeder.mechanics.candidates import variants_from_config
        from feeder.mechanics.features import push_block

        m, bins = self.meta, self.bins
        frame = self.frame_of(part)
        variants = variants_from_config(m["variants"])
        cand_cfg, memo = m["candidates"], {}
        config_ids, pool_ids = [str(c) for c in config_ids], [str(c) for c in pool_ids]
        cands = []
        for c in config_ids:
            cands.append(configuration_inputs(geom, memo, c, frame, scene, variants, cand_cfg, bins))
            if progress is not None and len(cands) % PROGRESS_EVERY == 0 and len(cands) < len(config_ids):
                progress(f"structured predictor: candidates of {len(cands)} of {len(config_ids)} configurations")
        q = row_inputs(cands, config_ids, m["n_variants"], int(cand_cfg["max_candidates"]), cand_cfg["present_mass"])
        n_pool, n_q = len(pool_ids), len(config_ids)
        rows = {
            "part": np.array([part] * (n_pool + n_q)),
            "config_id": np.array(pool_ids + config_ids),
            "kept": np.arange(n_pool + n_q) < n_pool,
            "analytic": np.concatenate([np.zeros((n_pool, bins)), q["analytic"]]),
            "pmf": np.concatenate(
                [np.reshape(np.asarray(pool_pmf, np.float64), (n_pool, bins)), np.zeros((n_q, bins))]
            ),
            "ok": np.concatenate([np.asarray(pool_ok, np.float64), q["analytic_ok"]]),
            "analytic_ok": np.concatenate([np.zeros(n_pool), q["analytic_ok"]]),
        }
        if m.get("mirror_labels"):  # its one-fence labels read at the other location too, as in training
            rows["mirror_deg"] = np.full(n_pool + n_q, self.mirror_deg(part))
        # the analytic PMFs of the pool rows that are some query's neighbour (a mirrored label's: its
        # source's), or whose miss is not kept
        source, source_pool, mirrored = with_mirrors(rows, rows["kept"])
        idx, _ = neighbour_rows(
            rows, rows["kept"], m["neighbours"], m["cross_neighbours"], source=(source, source_pool)
        )
        source_of = np.concatenate([np.arange(n_pool + n_q), mirrored])
        near = source_of[idx[n_pool:][idx[n_pool:] >= 0]]
        miss = np.array([self.miss.get((part, c), np.nan) for c in pool_ids] + [0.0] * n_q)
        for i in sorted(set(near.tolist()) | set(np.flatnonzero(np.isnan(miss)).tolist())):
            rows["analytic"][i] = push_block(
                geom,
                *parse_config_id(pool_ids[i]),
                scene,
                frame_deg=frame,
                bins=bins,
                pmf_smooth_deg=float(cand_cfg["label_smooth_deg"]),
                responses=memo,
            )[1]
            if np.isnan(miss[i]):
                miss[i] = label_miss(rows["pmf"][i], rows["analytic"][i])[0]
        feats, npmf = neighbour_block(
            rows,
            rows["kept"],
            m["neighbours"],
            m["neighbour_near_deg"],
            m["cross_neighbours"],
            miss,
            signed=bool(m.get("neighbour_signed", False)),  # a file from before the setting: false
        )
        blocks = [q["x"], feats[n_pool:]]
        if self.composes:  # the part's one-fence maps composed, as the protocol's with_composed
            rows["frame_deg"] = np.full(n_pool + n_q, frame)
            rows["composed_maps"] = {"maps": dict(pool_maps or {}), "sigma_bins": m["sigma_bins"], "memo": {}}
            c_feats, c_pmf = composed_block(
                rows, rows["kept"], m["neighbour_near_deg"], np.arange(n_pool, n_pool + n_q)
            )
            blocks.append(c_feats[n_pool:])
            npmf = np.concatenate([npmf, c_pmf], axis=1)
        raw = np.concatenate(blocks, axis=1)
        # calibration.network: the network's own analytic component is the part's calibrated mode's PMF
        own_analytic = q["analytic"]
        mode = self.part_mode(part)
        if mode is not None:
            from feeder.mechanics.candidates import variant_pmf

            smooth = float(cand_cfg["label_smooth_deg"])
            own_analytic = np.stack(
                [
                    variant_pmf(
                        geom,
                        *parse_config_id(c),
                        scene,
                        mode,
                        frame_deg=frame,
                        bins=bins,
                        smooth_deg=smooth,
                        responses=memo,
                    )[0]
                    for c in config_ids
                ]
            )
        # the specialist (when shipped) answers the queries with no label of their own type combination
        own = (idx[n_pool:, : m["neighbours"]] >= 0).any(axis=1)
        which = np.where(own | ("specialist" not in self.networks), "default", "specialist")
        out = np.zeros((n_q, bins))
        for name in sorted(set(which)):
            net, mine = self.networks[name], np.flatnonzero(which == name)
            if raw.shape[1] != np.size(net["x_mean"]):  # its settings say other inputs than it was fitted on
                raise FeederError(
                    f"the structured predictor's {name} network takes {np.size(net['x_mean'])} inputs and its "
                    f"file's settings build {raw.shape[1]}: refit it (feeder fit-structured) with this feeder"
                )
            x = (raw - net["x_mean"]) / net["x_sd"]
            diffuse = diffuse_components(own_analytic, net["mean_pmf"], m["wide_sigma_bins"], npmf[n_pool:])
            b = batch_inputs(dict(q, x=x), mine, diffuse[mine], net["settings"].start)
            for params in net["params"]:
                pmf = np.clip(forward_numpy(params, net["settings"], m["n_variants"], b), 0.0, None)
                out[mine] += pmf / pmf.sum(axis=1, keepdims=True)
            out[mine] /= len(net["params"])
            if blends_anything(net["blend"]):  # blend.weights (and blend.by_fallback), as the protocol
                fallback, from_label = self._fallback(rows, n_pool + mine, own_analytic[mine], net["blend"]["gate_deg"])
                out[mine] = blended(out[mine], fallback, row_weights(net["blend"], from_label))
        return out

    @staticmethod
    def _fallback(rows: dict, queries, analytic, gate_deg) -> tuple[np.ndarray, np.ndarray]:
        """The blend's fallback of the query rows ``queries`` of ``rows`` (pool rows kept):
        :func:`feeder.learn.structured_blend.gated_pmfs` from the pool with the part's
        (calibrated) ``analytic`` PMFs, or those alone when ``gate_deg`` is None; and per query
        whether its fallback is a neighbour's label."""
        from feeder.learn.structured_blend import fallback_choice

        if gate_deg is None:
            return np.asarray(analytic, np.float64).copy(), np.zeros(len(analytic), dtype=bool)
        own = np.array(rows["analytic"], dtype=np.float64)
        own[queries] = analytic
        return fallback_choice(dict(rows, analytic=own), rows["kept"], queries, gate_deg)


# ----------------------------------------------------------------------------------------------
# feeder fit-structured
# ----------------------------------------------------------------------------------------------
def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder fit-structured", description=__doc__.split("\n\n")[0])
    parser.add_argument("--dataset", type=Path, required=True, help="results/datasets/dataset.npz")
    parser.add_argument("--sim-dir", type=Path, required=True, help="results/sim (the ok shares)")
    parser.add_argument("--parts-dir", type=Path, required=True, help="the parts' STLs (parts)")
    parser.add_argument("--features-dir", type=Path, required=True, help="results/features (frames of excluded parts)")
    parser.add_argument("--out", type=Path, required=True, help="the .npz to write")
    parser.add_argument("--cache", type=Path, default=None, help="the candidates cache (.npz), read and written")
    parser.add_argument("overrides", nargs="*", help="Hydra overrides of config/hydra/structured.yaml")
    args = parser.parse_args(argv)
    from feeder import io
    from feeder.config import compose_config
    from feeder.labels.dataset import load_dataset
    from feeder.learn.structured_calibration import calibration_network, calibration_settings
    from feeder.learn.structured_data import one_fence_maps, structured_arrays
    from feeder.learn.structured_mirror import mirror_labels
    from feeder.learn.structured_protocol import check_count, composed_on

    if args.out.suffix != ".npz":
        raise FeederError(f"--out {args.out}: the file to write ends in .npz")
    cfg = compose_config("structured", args.overrides)
    check_count(cfg.seeds, "seeds")
    check_count(cfg.train.threads, "train.threads")
    composed_on(cfg)  # a bad value: a one-line error before any work
    calibration_settings(cfg)
    mirror_labels(cfg)
    if not cfg.search:
        raise FeederError("search: at least one setting to try (config/hydra/structured.yaml)")
    if not args.dataset.is_file():
        raise FeederError(f"{args.dataset} is missing")
    data = load_dataset(args.dataset)
    if "push_raw" not in data:
        raise FeederError(f"{args.dataset}: no push block (build the dataset with the part files)")
    import torch

    torch.set_num_threads(int(cfg.train.threads))
    say = lambda msg: print(f"feeder fit-structured: {msg}", file=sys.stderr, flush=True)  # noqa: E731
    calibrate = calibration_network(cfg)  # a bad calibration section: a one-line error before any work
    arrays = structured_arrays(
        data, cfg, args.sim_dir, args.parts_dir, args.features_dir, args.cache, say, calibration=calibrate
    )
    if composed_on(cfg):  # the one-fence configurations' drop maps, read from their simulation files
        sigma = float(json.loads(str(data["settings"]))["labels"]["sigma_bins"])
        arrays["composed_maps"] = one_fence_maps(arrays, args.sim_dir, sigma)
    say(f"training on {len(arrays['part'])} configurations of {len(set(arrays['part']))} parts")
    out = fit_shipped(arrays, cfg, data)
    io.write_npz(args.out, **out)
    meta = json.loads(str(out["meta"]))
    choice, sp = meta["choice"], (meta.get("specialist") or {}).get("choice")
    specialist = (
        ""
        if sp is None
        else (
            f"; Fences specialist {sp['kind']} (hidden {sp['hidden']}), validation circular W1 {sp['val_cw1']:.2f} deg"
        )
    )
    say(
        f"{choice['kind']} (hidden {choice['hidden']}), validation circular W1 {choice['val_cw1']:.2f} deg "
        f"({choice['val_parts']} validation part{'' if choice['val_parts'] == 1 else 's'}"
        f"{'; refit on ' + str(choice['refit_rows']) + ' rows' if choice.get('refit_rows') else ''}){specialist}"
        f" -> {args.out}"
    )
    return 0
