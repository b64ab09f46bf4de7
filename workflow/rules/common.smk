# Shared helpers for every rules file: config validation, the part and configuration lists,
# and the package modules each stage runs (declared as inputs so a code change reruns the stage;
# Snakemake does not track imported Python modules by itself).
import json

from snakemake.utils import validate

from feeder.datasets import configurations
from feeder.fences import parse_config_id
from feeder.parts import list_parts
from feeder.workflow import drop_local_job_rate_limit, module_files, put_interpreter_on_path, select_settings


validate(config, schema="../schemas/config.schema.yaml")

put_interpreter_on_path()

PARTS = list_parts(config["parts"]["dir"], config["parts"]["include"])
CONFIGS = configurations(config, PARTS)

def sim_path(part, config_id):
    return f"results/sim/{part}/{config_id}.npz"


def pkg(*modules):
    """Source files of the feeder modules a job runs, with the shared core (inputs)."""
    return module_files(*modules)


def settings_json(*keys):
    """Config sections or single dotted settings as JSON, for a rule's params."""
    return select_settings(config, *keys)


def figure_code(name, *shared):
    """Source files that draw one figure (inputs of its drawing job only): the module
    src/feeder/figures/<name>.py, any shared drawing modules it imports (e.g. _cdf_predictions),
    the shared style, the package's __init__ and the core."""
    files = pkg() + [f"src/feeder/figures/{m}.py" for m in ("__init__", "style", *shared, name)]
    missing = [f for f in files if not exists(f)]
    if missing:
        raise ValueError(f"figure_code: no drawing module {', '.join(missing)}")
    return files


def sim_settings():
    """Scene + the one preset the workflow uses: an edit to either reruns the simulations."""
    name = config["sim"]["preset"]
    return json.dumps(
        {"scene": config["scene"], "presets": {name: config["sim"]["presets"][name]}},
        sort_keys=True,
        separators=(",", ":"),
    )


def fence_location(index):
    """Command-line form (straight:30) of Location 1 (index 0) or 2 (index 1) of a job's fence id."""
    return lambda wildcards: parse_config_id(wildcards.fence)[index].spec
