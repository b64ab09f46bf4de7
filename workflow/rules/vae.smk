# The VAE (paper §3.4.2, Table 9), the partial-iteration study P2 (Fig. 14, p2_levels) and the
# delta-to-full correction sweep P4 (Table 10, Fig. S11). Uses DATASET (datasets.smk), code (common.smk). Figs. 14 and S11 are drawn by their own jobs from p2_levels.csv and
# table10.csv. Model settings: config/hydra/vae.yaml and config/hydra/delta.yaml (Hydra); the workflow's
# `vae:` and `delta:` sections choose the levels and add Hydra overrides (smoke shrinks epochs).
#
# Every training job gets the resolved Hydra config as a param, so editing a setting reruns
# exactly the jobs it affects; one job per level lets the levels run in parallel.
import shlex

from feeder.learn.vae import rule_params, select_levels

P2_LEVELS = select_levels(config["vae"]["p2_levels"], config["labels"]["levels_pct"], "vae.p2_levels")
DELTA_LEVELS = select_levels(config["delta"]["levels"], config["labels"]["levels_pct"], "delta.levels")
VAE_OVERRIDES = [f"dataset={DATASET}", *config["vae"]["hydra_overrides"]]
DELTA_OVERRIDES = [f"dataset={DATASET}", *config["delta"]["hydra_overrides"]]
VAE_HYDRA = rule_params("vae", VAE_OVERRIDES)
DELTA_HYDRA = rule_params("delta", DELTA_OVERRIDES)

VAE_TARGETS = [
    f"{RESULTS}/tables/table9.csv",
    f"{RESULTS}/tables/table9.md",
    f"{RESULTS}/tables/p2_levels.csv",
    f"{RESULTS}/tables/p2_levels.md",
    f"{RESULTS}/figures/fig14_cross_convergence.png",
    f"{RESULTS}/tables/table10.csv",
    f"{RESULTS}/tables/table10.md",
    f"{RESULTS}/figures/s11_delta_sweep.png",
]


rule vae_train:
    """Train the Table 9 VAE on the Main rows (train + test splits) only."""
    input:
        code("vae"),
        dataset=DATASET,
    output:
        f"{RESULTS}/vae/main.pt",
    log:
        f"{LOGS}/vae/train.log",
    benchmark:
        f"{BENCHMARKS}/vae/train.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        hydra=VAE_HYDRA["resolved"],
        overrides=VAE_HYDRA["overrides"],
    shell:
        "feeder vae train --out {output} {params.overrides} > {log} 2>&1"


rule vae_table9:
    """Table 9: reconstruction R² of features and CDFs on the Fences and Parts rows."""
    input:
        code("vae"),
        dataset=DATASET,
        model=f"{RESULTS}/vae/main.pt",
    output:
        csv=report(f"{RESULTS}/tables/table9.csv", caption="../report/table9.rst", category="VAE and delta"),
        md=report(f"{RESULTS}/tables/table9.md", caption="../report/table9.rst", category="VAE and delta"),
    log:
        f"{LOGS}/vae/table9.log",
    benchmark:
        f"{BENCHMARKS}/vae/table9.tsv"
    conda:
        "../envs/feeder.yaml"
    shell:
        "feeder vae table9 --model {input.model} --out {output.csv} > {log} 2>&1"


rule vae_p2_level:
    """P2: a VAE trained from scratch on the level-{level} CDFs of the shared 80 % split."""
    input:
        code("vae"),
        dataset=DATASET,
    output:
        f"{RESULTS}/vae/p2/level_{{level}}.json",
    log:
        f"{LOGS}/vae/p2_level_{{level}}.log",
    benchmark:
        f"{BENCHMARKS}/vae/p2_level_{{level}}.tsv"
    wildcard_constraints:
        level=r"\d+",
    conda:
        "../envs/feeder.yaml"
    params:
        hydra=VAE_HYDRA["resolved"],
        overrides=VAE_HYDRA["overrides"],
    shell:
        "feeder vae p2-level --level {wildcards.level} --out {output} {params.overrides} > {log} 2>&1"


rule vae_p2_gather:
    """P2 table of every level (within-level vs cross-convergence R², the data of Fig. 14)."""
    input:
        code("vae"),
        levels=expand(f"{RESULTS}/vae/p2/level_{{level}}.json", level=P2_LEVELS),
    output:
        csv=report(f"{RESULTS}/tables/p2_levels.csv", caption="../report/p2_levels.rst", category="VAE and delta"),
        md=report(f"{RESULTS}/tables/p2_levels.md", caption="../report/p2_levels.rst", category="VAE and delta"),
    log:
        f"{LOGS}/vae/p2_gather.log",
    benchmark:
        f"{BENCHMARKS}/vae/p2_gather.tsv"
    conda:
        "../envs/feeder.yaml"
    shell:
        "feeder vae p2-gather --table {output.csv} {input.levels} > {log} 2>&1"


rule delta_sweep_level:
    """P4: delta-to-full models at one level, part-level GroupKFold and random configuration folds."""
    input:
        code("delta"),
        dataset=DATASET,
    output:
        f"{RESULTS}/delta/level_{{level}}.json",
    log:
        f"{LOGS}/delta/level_{{level}}.log",
    benchmark:
        f"{BENCHMARKS}/delta/level_{{level}}.tsv"
    wildcard_constraints:
        level=r"\d+",
    conda:
        "../envs/feeder.yaml"
    params:
        hydra=DELTA_HYDRA["resolved"],
        overrides=DELTA_HYDRA["overrides"],
    shell:
        "feeder delta sweep --level {wildcards.level} --out {output} {params.overrides} > {log} 2>&1"


rule delta_table:
    """Table 10 (every swept level in the CSV, the paper's representative rows in the .md; the CSV
    is the data of Fig. S11)."""
    input:
        code("delta"),
        levels=expand(f"{RESULTS}/delta/level_{{level}}.json", level=DELTA_LEVELS),
    output:
        csv=report(f"{RESULTS}/tables/table10.csv", caption="../report/table10.rst", category="VAE and delta"),
        md=report(f"{RESULTS}/tables/table10.md", caption="../report/table10.rst", category="VAE and delta"),
    log:
        f"{LOGS}/delta/table.log",
    benchmark:
        f"{BENCHMARKS}/delta/table.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        hydra=DELTA_HYDRA["resolved"],
        overrides=" ".join(f"--override {shlex.quote(o)}" for o in DELTA_OVERRIDES),
    shell:
        "feeder delta table --table {output.csv} {params.overrides}" " {input.levels} > {log} 2>&1"
