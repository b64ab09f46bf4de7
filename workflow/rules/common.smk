# Shared helpers for every rules file: config validation, the part and configuration lists,
# and code(): the package modules a job runs, derived from its command's imports (declared as
# inputs so a code change reruns the job; Snakemake does not track imported Python modules).
import json
from pathlib import Path

from snakemake.utils import validate

from feeder.bench.reference import entries as design_bench_entries
from feeder.config import STUDY_SCHEMA, check_study_config
from feeder.labels.grid import configurations, protocol_parts
from feeder.lane.fences import parse_config_id
from feeder.parts.library import list_parts
from feeder.workflow import (
    cli_options,
    code_inputs,
    drop_local_job_rate_limit,
    put_interpreter_on_path,
    select_settings,
    simulations_notice,
)

try:
    validate(config, schema="../schemas/config.schema.yaml")
except Exception:
    # Snakemake's message quotes the whole schema; the same check names the setting in one line
    check_study_config(config, "config", Path(workflow.basedir) / STUDY_SCHEMA)
    raise
check_study_config(config, "config", Path(workflow.basedir) / STUDY_SCHEMA)  # and what no schema can say

# Every output of a run goes under its results directory (config key `results`), so overlays never
# overwrite each other's files: the default study writes results/ (and logs/, benchmarks/), an
# overlay its own folder, e.g. results/smoke/ with results/smoke/logs/ and results/smoke/benchmarks/.
RESULTS = config["results"]
LOGS, BENCHMARKS = ("logs", "benchmarks") if RESULTS == "results" else (f"{RESULTS}/logs", f"{RESULTS}/benchmarks")

put_interpreter_on_path()

PARTS = list_parts(config["parts"]["dir"], config["parts"]["include"], config["parts"].get("exclude", []))
CONFIGS = configurations(config, PARTS)
# the parts of the paper's Main/Fences/Parts protocol: every part but the wider library (datasets.wide)
PROTOCOL_PARTS = protocol_parts(config, PARTS)


def sim_path(part, config_id):
    return f"{RESULTS}/sim/{part}/{config_id}.npz"


def code(command, *args):
    """Source files a `feeder COMMAND ARGS` job runs (its transitive feeder imports): the rule's
    code inputs, so a code edit reruns exactly the jobs whose code changed."""
    return code_inputs(command, *args)


def settings_json(*keys):
    """Config sections or single dotted settings as JSON, for a rule's params."""
    return select_settings(config, *keys)


def sim_settings():
    """Scene + the one preset the workflow uses: an edit to either reruns the simulations."""
    name = config["sim"]["preset"]
    return json.dumps(
        {"scene": config["scene"], "presets": {name: config["sim"]["presets"][name]}},
        sort_keys=True,
        separators=(",", ":"),
    )


def design_options():
    """`feeder simulate` options of the adaptive design (sim.adaptive); none for the other
    designs, so editing sim.adaptive reruns only adaptive simulations."""
    if config["sim"]["yaw_sampling"] != "adaptive":
        return ""
    options = dict(config["sim"]["adaptive"])
    if config["sim"].get("adaptive_stop", "budget") == "target":  # budget: the command line as before the switch
        options |= {"stop": "target", **config["sim"]["adaptive_target"]}
    return cli_options({key.replace("_", "-"): value for key, value in options.items()})


def fence_location(index):
    """Command-line form (straight:30) of Location 1 (index 0) or 2 (index 1) of a job's fence id."""
    return lambda wildcards: parse_config_id(wildcards.fence)[index].spec
