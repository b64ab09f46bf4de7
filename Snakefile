# The feeder study: parts -> simulation -> features -> labels/datasets -> models -> tables/figures.
# All logic lives in the `feeder` package (src/feeder); rules only wire files to `feeder` commands.
# Default: the paper-scale study (config/config.yaml). Tiny version: --configfile config/smoke.yaml.

configfile: "config/config.yaml"


include: "workflow/rules/common.smk"
include: "workflow/rules/parts.smk"
include: "workflow/rules/simulate.smk"
include: "workflow/rules/datasets.smk"
include: "workflow/rules/models.smk"
include: "workflow/rules/vae.smk"
include: "workflow/rules/report.smk"


rule all:
    input:
        ALL_TARGETS,
    default_target: True
