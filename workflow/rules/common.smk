# Shared helpers for every rules file: config validation, the part and configuration lists,
# and the package modules each stage runs (declared as inputs so a code change reruns the stage;
# Snakemake does not track imported Python modules by itself).
import json
import os
import sys

from snakemake.utils import validate

from feeder.datasets import configurations
from feeder.parts import list_parts


validate(config, schema="../schemas/config.schema.yaml")

# Jobs call `feeder`: take it from the environment Snakemake itself runs in (e.g. .venv/bin),
# even when that environment is not activated.
os.environ["PATH"] = os.pathsep.join([os.path.dirname(sys.executable), os.environ.get("PATH", "")])

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


def settings_json(*keys):
    """The named config sections (``labels``) or single settings (``sim.min_ok_drops``) as compact
    JSON with their nesting kept: passed as a param so editing exactly these reruns the rule."""
    picked = {}
    for key in keys:
        *path, last = key.split(".")
        src, dst = config, picked
        for name in path:
            src, dst = src[name], dst.setdefault(name, {})
        dst[last] = src[last]
    return json.dumps(picked, sort_keys=True, separators=(",", ":"))
