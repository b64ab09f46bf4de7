"""Every settings loader of the package, one of each.

Two kinds of settings:

* the study settings (``config/config.yaml`` and the overlays ``smoke.yaml``, ``dense.yaml`` …),
  which the workflow reads with Snakemake's ``--configfile`` and hands to each command as a
  ``--settings`` JSON of the sections it needs: :func:`load_study_config` (what
  ``snakemake --configfile <overlays>`` sees, for commands run outside the workflow; with
  :func:`study_root`, where that study is; checked against the workflow's schema by
  :func:`check_study_config`) and :func:`parse_settings` (a command's ``--settings``);
* the model settings, Hydra files under ``config/hydra/`` (``train.yaml`` with the groups
  ``model/``, ``trainer/``, ``hparams_search/``; ``vae.yaml``; ``delta.yaml``):
  :func:`hydra_config_dir` (where they are), :func:`compose_config` (one composed config) and
  :func:`resolved_yaml` (its resolved text, a workflow rule param).

Every problem is a :class:`~feeder.errors.FeederError` with a one-line message. Importing this
module is cheap (yaml, Hydra and OmegaConf are imported where used): the workflow calls it at
parse time.
"""

from __future__ import annotations

import functools
import json
import os
from collections.abc import Sequence
from pathlib import Path

from feeder.errors import FeederError

HYDRA_SUBDIR = Path("config") / "hydra"  # relative to a study directory (or the repository)
STUDY_CONFIG = Path("config") / "config.yaml"  # likewise
STUDY_SCHEMA = Path("workflow") / "schemas" / "config.schema.yaml"  # what Snakemake validates at start
PROJECT_ENV = "FEEDER_PROJECT"  # names the project a command outside the workflow reads


# ----------------------------------------------------------------------------------------------
# Study settings
# ----------------------------------------------------------------------------------------------
def parse_settings(text: str, *sections: str) -> dict:
    """The ``--settings`` JSON of a command (config sections, as the workflow passes them), with
    the named top-level sections required; a one-line :class:`FeederError` otherwise."""
    try:
        obj = json.loads(text)
    except json.JSONDecodeError as err:
        raise FeederError(f"--settings is not valid JSON: {err.msg}") from None
    if not isinstance(obj, dict):
        raise FeederError("--settings must be a JSON object of config sections")
    missing = [s for s in sections if s not in obj]
    if missing:
        raise FeederError(f"--settings lacks the config section(s): {', '.join(missing)}")
    return obj


def overlay_config(base: dict, over: dict) -> dict:
    """``base`` with ``over`` laid on top, nested sections merged key by key (the way Snakemake
    merges ``--configfile`` files). Modifies and returns ``base``."""
    for key, value in over.items():
        if isinstance(value, dict) and isinstance(base.get(key), dict):
            overlay_config(base[key], value)
        else:
            base[key] = value
    return base


def load_study_config(*overlays: str | os.PathLike, root: str | os.PathLike = ".", check: bool = False) -> dict:
    """config/config.yaml of the study in ``root`` overlaid by the given files (paths relative to
    ``root`` unless absolute), as ``snakemake --configfile <overlays>`` sees it; with ``check``,
    validated as the workflow validates it (:func:`check_study_config`)."""
    import yaml

    merged: dict = {}
    paths = [Path(root) / name for name in (STUDY_CONFIG, *overlays)]
    for path in paths:
        if not path.is_file():
            raise FeederError(
                f"config file {path} not found (run inside the project, set ${PROJECT_ENV} to it, or pass --settings)"
            )
        try:
            data = yaml.load(path.read_text(), Loader=_yaml_loader()) or {}
        except (yaml.YAMLError, UnicodeDecodeError) as err:
            raise FeederError(f"config file {path} is not valid YAML: {_one_line(str(err))}") from None
        if not isinstance(data, dict):
            raise FeederError(f"config file {path} is not a mapping of config sections")
        overlay_config(merged, data)
    if check:
        check_study_config(merged, " + ".join(map(str, paths)), study_schema(root))
    return merged


def _one_line(text: str) -> str:
    return " ".join(text.split())


def _yaml_loader():
    """yaml's safe loader, its libyaml build when there is one (the same YAML, parsed faster)."""
    import yaml

    return getattr(yaml, "CSafeLoader", yaml.SafeLoader)


@functools.lru_cache(maxsize=4)
def _schema_validator(path: Path, mtime_ns: int):
    import jsonschema
    import yaml

    spec = yaml.load(path.read_text(), Loader=_yaml_loader())
    return jsonschema.validators.validator_for(spec)(spec)


def study_schema(root: str | os.PathLike = ".") -> Path:
    """The config schema of the study in ``root``, else the repository's (next to the package)."""
    local = Path(root) / STUDY_SCHEMA
    return local if local.is_file() else package_project() / STUDY_SCHEMA


def check_study_config(config: dict, source: str = "config", schema: str | os.PathLike | None = None) -> dict:
    """``config`` checked against the workflow's schema (``workflow/schemas/config.schema.yaml``,
    what Snakemake validates at start); the first problem is a one-line :class:`FeederError`
    naming ``source`` and the setting (``sim.drops: -5 is less than the minimum of 1``)."""
    import jsonschema

    path = Path(schema if schema is not None else study_schema()).resolve()
    validator = _schema_validator(path, path.stat().st_mtime_ns)
    error = jsonschema.exceptions.best_match(validator.iter_errors(config))
    if error is not None:
        where = ".".join(map(str, error.absolute_path)) or "top level"
        raise FeederError(f"{source}: {where}: {_one_line(error.message)}")
    sim = config.get("sim") or {}
    if "preset" in sim and "presets" in sim and sim["preset"] not in sim["presets"]:  # what no schema can say
        raise FeederError(
            f"{source}: sim.preset: {sim['preset']!r} is not one of sim.presets ({', '.join(map(str, sim['presets']))})"
        )
    return config


def package_project() -> Path:
    """The project the package belongs to: the repository that holds ``src/feeder``."""
    return Path(__file__).resolve().parents[2]


def project_override() -> Path | None:
    """The project named by ``$FEEDER_PROJECT`` (:data:`PROJECT_ENV`), or None when it is unset;
    a one-line :class:`FeederError` when it names no project (no ``config/config.yaml`` there)."""
    named = os.environ.get(PROJECT_ENV)
    if not named:
        return None
    root = Path(named).expanduser().resolve()
    if not (root / STUDY_CONFIG).is_file():
        raise FeederError(f"${PROJECT_ENV}={named} names no project: {root / STUDY_CONFIG} not found")
    return root


def study_root(cwd: str | os.PathLike | None = None) -> Path:
    """The study directory of a command run outside the workflow without ``--settings``, found as
    git finds its repository: ``$FEEDER_PROJECT`` when set (:func:`project_override`), else the
    working directory or the nearest folder above it that holds ``config/config.yaml``, else the
    project of the package (:func:`package_project`, like :func:`hydra_config_dir`). When none
    holds it, the working directory, so that :func:`load_study_config` names the file it looked
    for there."""
    override = project_override()
    if override is not None:
        return override
    local = Path(cwd or os.getcwd()).resolve()
    for folder in (local, *local.parents):
        if (folder / STUDY_CONFIG).is_file():
            return folder
    repo = package_project()
    return repo if (repo / STUDY_CONFIG).is_file() else local


def project_path(path: str | os.PathLike) -> Path:
    """A path named relative to the project (``parts``, ``models/m3prior``): as given when it is
    absolute or exists from the working directory, else in the project (:func:`study_root`) when
    it exists there, else as given (so that an error names what was asked for)."""
    path = Path(path)
    if path.is_absolute() or path.exists():
        return path
    in_project = study_root() / path
    return in_project if in_project.exists() else path


# ----------------------------------------------------------------------------------------------
# Model settings (Hydra)
# ----------------------------------------------------------------------------------------------
def hydra_config_dir(cwd: str | os.PathLike | None = None) -> str:
    """Where the Hydra model settings live: ``config/hydra/`` of the project named by
    ``$FEEDER_PROJECT`` when set, else of the directory the study runs in (the workflow's working
    directory, like ``config/config.yaml``), else the repository's own ``config/hydra/`` next to
    the package. Parse-time params and the jobs both read this one place."""
    override = project_override()
    if override is not None and (override / HYDRA_SUBDIR).is_dir():
        return str(override / HYDRA_SUBDIR)
    local = Path(cwd or os.getcwd()) / HYDRA_SUBDIR
    if local.is_dir():
        return str(local.resolve())
    return str(package_project() / HYDRA_SUBDIR)


def compose_config(name: str, overrides: Sequence[str] = (), config_dir: str | os.PathLike | None = None):
    """Compose ``<name>.yaml`` of the Hydra directory (default :func:`hydra_config_dir`) with
    Hydra overrides: Hydra's compose API, version_base 1.3, no output directory, no logging
    setup. A bad override or file is a one-line :class:`FeederError`."""
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra
    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    config_dir = Path(config_dir or hydra_config_dir()).resolve()
    overrides = [str(o) for o in overrides]
    if GlobalHydra.instance().is_initialized():
        GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(version_base="1.3", config_dir=str(config_dir), job_name=f"feeder_{name}"):
            return compose(config_name=name, overrides=overrides)
    except (HydraException, OmegaConfBaseException) as err:
        first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise FeederError(f"{config_dir / name}.yaml with overrides {overrides}: {first}") from None


def pull_overrides(values, overrides: Sequence[str]) -> tuple[list, list[str]]:
    """``(values, overrides)`` with every Hydra override (a ``key=value`` word that names no
    existing file) moved from ``values`` to the end of ``overrides``. argparse hands a list option
    (``nargs``) every word after it, so ``--m3-model a b protocol.fits=[main]`` would otherwise
    read the override as a path. ``values`` None stays None."""
    if values is None:
        return None, list(overrides)

    def is_override(word: str) -> bool:
        return "=" in word and not word.startswith("=") and not Path(word).exists()

    kept = [v for v in values if not is_override(str(v))]
    moved = [str(v) for v in values if is_override(str(v))]
    return kept, [*overrides, *moved]


def resolved_yaml(
    name: str, overrides: Sequence[str] = (), drop: Sequence[str] = (), config_dir: str | os.PathLike | None = None
) -> str:
    """The composed config, fully resolved, as YAML text, without the top-level keys ``drop``
    (settings that do not change a result, like output paths). As a Snakemake ``params:`` value
    it reruns a job exactly when one of its settings changes."""
    from omegaconf import OmegaConf

    cfg = compose_config(name, overrides, config_dir)
    keep = OmegaConf.create({k: cfg[k] for k in cfg if k not in drop})
    return OmegaConf.to_yaml(OmegaConf.create(OmegaConf.to_container(keep, resolve=True)))


def add_settings_options(parser):
    """``--settings JSON`` (what the workflow passes) and ``--configfile OVERLAY`` (repeatable) on a
    command's parser; :func:`study_settings` reads them. Returns the parser."""
    parser.add_argument("--settings", default=None, help="JSON of the config sections (the workflow passes it)")
    parser.add_argument("--configfile", action="append", default=None, help="an overlay of config/config.yaml")
    return parser


def study_settings(args, *sections: str) -> dict:
    """The settings named by :func:`add_settings_options`: the JSON (which must hold the config
    ``sections`` the command reads), else config/config.yaml of the study (:func:`study_root`)
    with the overlays laid on top, checked against the schema."""
    if args.settings:
        return parse_settings(args.settings, *sections)
    overlays = [str(Path(f).resolve()) for f in args.configfile or []]
    return load_study_config(*overlays, root=study_root(), check=True)
