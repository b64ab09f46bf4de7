# The paper's tables and figures as the default target, what the study cost, and every figure:
# one drawing job per figure (feeder figure NAME) from its data file, so a style edit redraws only
# that figure. FIGURE_TABLE is the one list of figures.

from feeder.parts.features import DFT

TABLES = f"{RESULTS}/tables"
FIGURES = f"{RESULTS}/figures"

PARTS_TARGETS = [
    f"{FIGURES}/fig6_dft_reconstruction.png",
    f"{TABLES}/s1_dft_mse.csv",
    f"{FIGURES}/s1_dft_mse.png",
]
SIM_TARGETS = [f"{TABLES}/table1.csv"]
# Every table and figure of the study (each stage's rules file lists its own).
PAPER_TARGETS = PARTS_TARGETS + SIM_TARGETS + DATASETS_TARGETS + MODELS_TARGETS + VAE_TARGETS

ALL_TARGETS = PAPER_TARGETS + [f"{TABLES}/cost_by_stage.csv", f"{FIGURES}/cost_by_stage.png"]


rule run_config:
    """The run's resolved config, on its own: any change of a setting rewrites it, and so the run's
    provenance below (whose inputs are ancient, so Snakemake would not look at its params while the
    jobs upstream of it rerun)."""
    input:
        code("cost"),
    output:
        f"{RESULTS}/run_config.json",
    log:
        f"{LOGS}/report/run_config.log",
    conda:
        "../envs/feeder.yaml"
    params:
        config=settings_json(*config),
    shell:
        "feeder cost --config-json '{params.config}' --config-out {output} > {log} 2>&1"


rule cost_by_stage:
    """Per-stage wall/CPU/memory from every job's benchmark file, once everything else is built."""
    input:
        # after every other result (order only): the record of a whole run, which a later redraw of
        # one figure does not make outdated (nor, in a clone, send back to the simulations)
        ancient(PAPER_TARGETS),
        code("cost"),
        config=f"{RESULTS}/run_config.json",
    output:
        csv=report(f"{TABLES}/cost_by_stage.csv", caption="../report/cost_by_stage.rst", category="Cost"),
        provenance=f"{RESULTS}/provenance.json",
    log:
        f"{LOGS}/report/cost_by_stage.log",
    benchmark:
        f"{BENCHMARKS}/report/cost_by_stage.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        benchmarks=BENCHMARKS,
    shell:
        "feeder cost --benchmarks {params.benchmarks} --out-csv {output.csv}"
        " --provenance {output.provenance} --config-file {input.config} > {log} 2>&1"


# name: data file it is drawn from, report caption, report category, extra `feeder figure` options
FIGURE_TABLE = {
    "fig6_dft_reconstruction": (
        f"{RESULTS}/figdata/fig6_dft_reconstruction.npz",
        "fig6_dft_reconstruction",
        "Parts",
        {},
    ),
    "s1_dft_mse": (f"{TABLES}/s1_dft_mse.csv", "s1_dft_mse", "Parts", {"chosen": DFT.coefficients}),
    "sim_accuracy_vs_time": (
        f"{TABLES}/sim_accuracy_vs_time.csv",
        "sim_accuracy_vs_time",
        "Simulation",
        {"reference": config["sim"]["bench"]["reference"]},
    ),
    "jam_rates": (f"{TABLES}/jam_rates.csv", "jam_rates_figure", "Simulation", {}),
    "contact_model": (f"{TABLES}/contact_model.csv", "contact_model_figure", "Simulation", {}),
    "contact_decomposition": (f"{TABLES}/contact_decomposition.csv", "contact_decomposition_figure", "Simulation", {}),
    "step_cost": (f"{TABLES}/step_cost.csv", "step_cost_figure", "Simulation", {}),
    "physics_sensitivity": (f"{TABLES}/physics_sensitivity.csv", "physics_sensitivity_figure", "Simulation", {}),
    "yaw_sampling": (f"{TABLES}/yaw_sampling.csv", "yaw_sampling", "Simulation", {}),
    "sim_cost": (f"{TABLES}/sim_cost_sample.csv", "sim_cost_figure", "Cost", {}),
    "frontier": (f"{TABLES}/frontier.csv", "frontier_figure", "Cost", {}),
    "frontier_known": (f"{TABLES}/frontier_known.csv", "frontier_known_figure", "Cost", {}),
    "label_designs": (f"{TABLES}/label_designs_summary.csv", "label_designs_figure", "Simulation", {}),
    "label_emulation": (f"{TABLES}/label_emulation.csv", "label_emulation_figure", "Simulation", {}),
    "fig4_js_vs_drops": (f"{RESULTS}/figdata/fig4_js_vs_drops.csv", "fig4_js_vs_drops", "Datasets", {}),
    "fig5_js_hist": (f"{RESULTS}/figdata/fig5_js_hist.npz", "fig5_js_hist", "Datasets", {}),
    "fig9_example_pmfs": (f"{RESULTS}/figdata/fig9_example_pmfs.npz", "fig9_example_pmfs", "Datasets", {}),
    "convergence_dkw": (f"{RESULTS}/figdata/convergence_dkw.npz", "convergence_dkw", "Datasets", {}),
    "label_error_estimate": (f"{TABLES}/label_error_estimate.csv", "label_error_estimate_figure", "Datasets", {}),
    "fig12_test_predictions": (f"{RESULTS}/figdata/fig12_test_predictions.npz", "fig12_test_predictions", "Models", {}),
    "fig13_parts_predictions": (
        f"{RESULTS}/figdata/fig13_parts_predictions.npz",
        "fig13_parts_predictions",
        "Models",
        {},
    ),
    "fig14_cross_convergence": (f"{TABLES}/p2_levels.csv", "fig14_cross_convergence", "VAE and delta", {}),
    "s11_delta_sweep": (f"{TABLES}/table10.csv", "s11_delta_sweep", "VAE and delta", {}),
    "cost_by_stage": (f"{TABLES}/cost_by_stage.csv", "cost_by_stage_figure", "Cost", {}),
}


for fig, (data, caption, category, options) in FIGURE_TABLE.items():

    rule:
        name:
            f"draw_{fig}"
        input:
            code("figure", fig),
            data=data,
        output:
            report(f"{FIGURES}/{fig}.png", caption=f"../report/{caption}.rst", category=category),
        log:
            f"{LOGS}/figures/{fig}.log",
        benchmark:
            f"{BENCHMARKS}/figures/{fig}.tsv"
        conda:
            "../envs/feeder.yaml"
        params:
            figure=fig,
            options=cli_options(options),
        shell:
            # no loop variable in here: Snakemake evaluates the shell string again when the job runs,
            # after the loop has moved on, so the figure's name comes in as a param
            "feeder figure {params.figure} --data {input.data} {params.options} --out {output} > {log} 2>&1"
