# The feeder study: parts -> simulation -> features -> labels/datasets -> models -> tables/figures.
# All logic lives in the `feeder` package (src/feeder); rules only wire files to `feeder` commands.
# Default: the paper-scale study (config/config.yaml). Tiny version: --configfile config/smoke.yaml.

from snakemake.utils import min_version

min_version("9.0")


configfile: "config/config.yaml"


envvars:
    "PATH",


wildcard_constraints:
    part=r"[A-Za-z0-9-]+",
    fence=r"[a-z0-9.]+_[a-z0-9.]+",
    model=r"m[1-8](push|pushonly|prior)?",
    seed=r"[0-9]+",


include: "workflow/rules/common.smk"
include: "workflow/rules/parts.smk"
include: "workflow/rules/simulate.smk"
include: "workflow/rules/datasets.smk"
include: "workflow/rules/models.smk"
include: "workflow/rules/vae.smk"
include: "workflow/rules/bench.smk"
include: "workflow/rules/report.smk"


onstart:
    # Snakemake 9's rate limiter re-schedules once per second per finished job (snakemake#3744):
    # measurable CPU on ~1,250 simulation jobs, and of no use on one machine.
    if not config["scheduling"]["local_rate_limit"]:
        drop_local_job_rate_limit(workflow, log=logger.info)
    # simulations are not committed: a run that needs them says so before the hours start
    notice = simulations_notice(
        workflow.dag.needrun_jobs(),
        workflow.dag.targetfiles or {rule.name for rule in workflow.dag.targetrules},
    )
    if notice:
        logger.warning(notice)


rule all:
    default_target: True
    input:
        ALL_TARGETS,
