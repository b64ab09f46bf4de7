"""The scene and simulation settings of a study: the ``scene`` config section and the presets,
from a ``--settings`` JSON or the study config."""

from __future__ import annotations

import os

from feeder.errors import FeederError


def load_settings(settings_json: str | None = None, root: str | os.PathLike | None = None):
    """``(scene, presets)`` from a ``--settings`` JSON string or else from the study config.

    The JSON holds ``{"scene": {...}, "presets": {...}}`` (or ``{"scene": ..., "sim": {"presets":
    ...}}``: the config sections as they are). Without it, ``config/config.yaml`` of the study in
    ``root`` is read by :func:`feeder.config.load_study_config`; ``root`` defaults to
    :func:`feeder.config.study_root` (the working directory when it holds that file, else the
    repository).
    """
    if settings_json is not None:
        from feeder.config import parse_settings

        data = parse_settings(settings_json)
    else:
        from feeder.config import load_study_config, study_root

        data = load_study_config(root=study_root() if root is None else root)
    presets = data.get("presets")
    if presets is None:
        presets = (data.get("sim") or {}).get("presets")
    scene = data.get("scene")
    if not isinstance(scene, dict):
        raise FeederError("settings lack the 'scene' section")
    if not isinstance(presets, dict) or not presets:
        raise FeederError("settings lack the simulation presets ('presets' or 'sim.presets')")
    return scene, presets
