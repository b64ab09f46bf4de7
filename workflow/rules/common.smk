# Shared helpers for every rules file: config validation, the part and configuration lists,
# and the package modules each stage runs (declared as inputs so a code change reruns the stage;
# Snakemake does not track imported Python modules by itself).
import json

from snakemake.utils import validate

from feeder.datasets import configurations
from feeder.parts import list_parts


validate(config, schema="../schemas/config.schema.yaml")

PARTS = list_parts(config["parts"]["dir"], config["parts"]["include"])
CONFIGS = configurations(config, PARTS)


wildcard_constraints:
    part=r"[A-Za-z0-9-]+",
    fence=r"[a-z0-9.]+_[a-z0-9.]+",
    model=r"m[1-8]",


def sim_path(part, config_id):
    return f"results/sim/{part}/{config_id}.npz"


def pkg(*modules):
    """Source files of the feeder modules a rule runs (always with the shared core)."""
    core = ("__init__", "cli", "errors", "io")
    return [f"src/feeder/{name}.py" for name in dict.fromkeys(core + modules)]


def settings_json(*sections):
    """The named config sections as compact JSON: passed as a param so an edit reruns the rule."""
    return json.dumps({name: config[name] for name in sections}, sort_keys=True, separators=(",", ":"))
