"""The simulator's answer for one part and configuration, as ``feeder predict --simulate`` and
``feeder recommend --verify`` give it: the study's adaptive design, labelled as the workflow labels."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from feeder.errors import FeederError


def verify_settings(study: dict) -> dict:
    """What ``--verify`` simulates with, from the study config: the scene, ``sim.preset``,
    ``sim.base_seed``, the adaptive design's settings (``sim.adaptive``) and budget (``sim.drops``
    when the study's design is adaptive, else the adaptive default), and the labels' bins and
    smoothing."""
    from feeder.sim.adaptive import DEFAULT_BUDGET
    from feeder.sim.drops import get_preset

    sim = study["sim"]
    return {
        "scene": study["scene"],
        "preset_name": sim["preset"],
        "preset": get_preset(sim["presets"], sim["preset"]),
        "seed": int(sim["base_seed"]),
        "budget": int(sim["drops"]) if sim["yaw_sampling"] == "adaptive" else DEFAULT_BUDGET,
        "adaptive": dict(sim["adaptive"]),
        "bins": int(study["labels"]["bins"]),
        "sigma": float(study["labels"]["sigma_bins"]),
    }


def status_counts(status) -> str:
    """The simulated drops by status, most frequent first (ties by name): ``"jammed 32"``,
    ``"ok 20, fell_off 12"``."""
    names, counts = np.unique(np.asarray(status).astype(str), return_counts=True)
    pairs = sorted(zip(names.tolist(), counts.tolist()), key=lambda nc: (-nc[1], nc[0]))
    return ", ".join(f"{name} {count}" for name, count in pairs)


def verify_part(part: Path | None):
    """The part ``--verify`` simulates: ``--part`` as an STL (a one-line FeederError otherwise,
    before any other work)."""
    if part is None or part.suffix.lower() != ".stl":
        raise FeederError("--verify simulates the part: give it as --part PART.stl")
    if not part.is_file():
        raise FeederError(f"part file {part} not found")
    from feeder.parts.geometry import load_part

    return load_part(part, "auto")


def simulated_frame(
    geom, loc1: str, loc2: str, budget: int, study: dict, audits: int = 0
) -> tuple[pd.DataFrame | None, dict]:
    """The answer of the simulator: ``geom`` through (``loc1``, ``loc2``) with the study's adaptive
    design at most ``budget`` drops (below ``sim.adaptive.n0`` an evenly spaced grid of ``budget``
    drops), labelled as the workflow labels (part frame). Returns the PMF/CDF frame (None when
    every drop jammed or fell off) and ``{ok_mass, statuses, simulations, cpu_s}``; with ``audits``
    > 0 also ``estimate`` and ``audit_cpu_s``: that many audit drops simulated beside the answer and
    its error estimate (:mod:`feeder.labels.audit`; ``sim.adaptive_target.confidence``)."""
    from feeder.labels.pmf import sim_label
    from feeder.lane.fences import parse_location
    from feeder.sim.record import record_of
    from feeder.sim.simulate import simulate

    if isinstance(budget, bool) or int(budget) != budget or budget < 2:
        raise FeederError(f"--simulate: a budget of at least 2 drops (got {budget!r})")
    settings = verify_settings(study)
    adaptive = dict(settings["adaptive"], n0=min(int(settings["adaptive"]["n0"]), int(budget)))
    result = simulate(
        geom,
        parse_location(loc1),
        parse_location(loc2),
        int(budget),
        settings["seed"],
        settings["scene"],
        settings["preset"],
        settings["preset_name"],
        yaw_sampling="adaptive",
        adaptive=adaptive,
    )
    rec = record_of(result)
    info = {"ok_mass": 0.0, "statuses": status_counts(rec.status), "simulations": int(rec.status.size)}
    info["cpu_s"] = float(result["cpu_s"])
    if not rec.ok.any():
        return None, info
    label = sim_label(rec, settings["bins"], settings["sigma"])
    info["ok_mass"] = float(label.ok_mass)
    if audits:
        from feeder.labels import audit as A

        drops = pd.DataFrame(A.audit_rows(rec, audits, A.simulator(geom, rec)))
        confidence = float(study["sim"]["adaptive_target"]["confidence"])
        info["estimate"] = A.estimate_from_audit(rec, drops, settings["bins"], settings["sigma"], confidence)
        info["audit_cpu_s"] = float(drops["cpu_s"].sum())
    bins = label.pmf.size
    frame = pd.DataFrame({"angle_deg": np.arange(bins) * (360.0 / bins), "pmf": label.pmf, "cdf": np.cumsum(label.pmf)})
    return frame, info
