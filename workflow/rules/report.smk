# The paper's tables and figures as the default target, and what the study cost.

TABLES = "results/tables"
FIGURES = "results/figures"

PARTS_TARGETS = [
    f"{FIGURES}/fig6_dft_reconstruction.png",
    f"{TABLES}/s1_dft_mse.csv",
    f"{FIGURES}/s1_dft_mse.png",
]
SIM_TARGETS = [
    f"{TABLES}/table1.csv",
    f"{TABLES}/sim_accuracy_vs_time.csv",
    f"{TABLES}/jam_rates.csv",
    f"{FIGURES}/jam_rates.png",
    f"{FIGURES}/sim_accuracy_vs_time.png",
    f"{TABLES}/yaw_sampling.csv",
    f"{FIGURES}/yaw_sampling.png",
    f"{TABLES}/sim_cost.csv",
    f"{FIGURES}/sim_cost.png",
]
# Every table and figure of the study (each stage's rules file lists its own).
PAPER_TARGETS = PARTS_TARGETS + SIM_TARGETS + DATASETS_TARGETS + MODELS_TARGETS + VAE_TARGETS

ALL_TARGETS = PAPER_TARGETS + [f"{TABLES}/cost_by_stage.csv", f"{FIGURES}/cost_by_stage.png"]


rule cost_by_stage:
    """Per-stage wall/CPU/memory from every job's benchmark file, once everything else is built."""
    input:
        PAPER_TARGETS,
        pkg("cost"),
    output:
        csv=report(f"{TABLES}/cost_by_stage.csv", caption="../report/cost_by_stage.rst", category="Cost"),
        provenance="results/provenance.json",
    params:
        config=settings_json(*config),
    log:
        "logs/report/cost_by_stage.log",
    benchmark:
        "benchmarks/report/cost_by_stage.tsv"
    conda:
        "../envs/feeder.yaml"
    shell:
        "feeder cost --benchmarks benchmarks --out-csv {output.csv}"
        " --provenance {output.provenance} --config-json '{params.config}' > {log} 2>&1"


rule draw_cost_by_stage:
    """The cost figure drawn from cost_by_stage.csv."""
    input:
        figure_code("cost_by_stage"),
        data=f"{TABLES}/cost_by_stage.csv",
    output:
        report(f"{FIGURES}/cost_by_stage.png", caption="../report/cost_by_stage_figure.rst", category="Cost"),
    log:
        "logs/figures/cost_by_stage.log",
    benchmark:
        "benchmarks/figures/cost_by_stage.tsv"
    conda:
        "../envs/feeder.yaml"
    shell:
        "feeder figure cost_by_stage --data {input.data} --out {output} > {log} 2>&1"
