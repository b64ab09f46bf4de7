# The paper's tables and figures as the default target, and what the study cost.

TABLES = "results/tables"
FIGURES = "results/figures"

PAPER_TARGETS = [
    f"{TABLES}/table1.csv",
    f"{TABLES}/table4.csv",
    *expand(f"{TABLES}/table{{n}}.csv", n=[5, 6, 7, 8]),
    f"{TABLES}/groupkfold_m3.csv",
    f"{TABLES}/table9.csv",
    f"{TABLES}/table10.csv",
    f"{TABLES}/p2_levels.csv",
    f"{TABLES}/s1_dft_mse.csv",
    f"{TABLES}/convergence_dkw.csv",
    f"{TABLES}/sim_accuracy_vs_time.csv",
    f"{FIGURES}/fig6_dft_reconstruction.png",
    f"{FIGURES}/fig12_test_predictions.png",
    f"{FIGURES}/fig13_parts_predictions.png",
    f"{FIGURES}/fig14_cross_convergence.png",
    f"{FIGURES}/s11_delta_sweep.png",
]

ALL_TARGETS = PAPER_TARGETS + [f"{TABLES}/cost_by_stage.csv"]


rule cost_by_stage:
    """Per-stage wall/CPU/memory from every job's benchmark file, once everything else is built."""
    input:
        PAPER_TARGETS,
        pkg("cost"),
    output:
        csv=report(f"{TABLES}/cost_by_stage.csv", caption="../report/cost_by_stage.rst", category="Cost"),
        fig=report(f"{FIGURES}/cost_by_stage.png", caption="../report/cost_by_stage.rst", category="Cost"),
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
        "feeder cost --benchmarks benchmarks --out-csv {output.csv} --out-fig {output.fig}"
        " --provenance {output.provenance} --config-json '{params.config}' > {log} 2>&1"
