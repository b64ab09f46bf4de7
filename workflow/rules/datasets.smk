# Labels and datasets: the configuration table, the merged dataset.npz, Table 4 and the label
# convergence study (Figs. 4, 5, 9 and the DKW view: one compute job writes their data to
# results/figdata/, one drawing job per figure). Uses PARTS, CONFIGS, sim_path, code
# and settings_json from common.smk.
import os

DATASET = f"{RESULTS}/datasets/dataset.npz"

DATASETS_TARGETS = [
    f"{RESULTS}/datasets/configurations.csv",
    DATASET,
    f"{RESULTS}/tables/table4.csv",
    f"{RESULTS}/tables/table4.md",
    f"{RESULTS}/tables/convergence_dkw.csv",
    f"{RESULTS}/tables/convergence_js.csv",
    f"{RESULTS}/figures/fig4_js_vs_drops.png",
    f"{RESULTS}/figures/fig5_js_hist.png",
    f"{RESULTS}/figures/fig9_example_pmfs.png",
    f"{RESULTS}/figures/convergence_dkw.png",
]
# every grid/adaptive label's error estimate (sim.label_audit): audit drops per part, then the table
AUDIT = config["sim"]["label_audit"] and config["sim"]["yaw_sampling"] in ("grid", "adaptive")
AUDIT_PARTS = sorted(set(CONFIGS["part"]))
if AUDIT:
    DATASETS_TARGETS += [
        f"{RESULTS}/tables/label_error_estimate.csv",
        f"{RESULTS}/tables/label_error_estimate_summary.csv",
        f"{RESULTS}/figures/label_error_estimate.png",
    ]


rule datasets_configurations:
    """The part x fence configuration table (dataset and split of every row)."""
    input:
        code("datasets"),
    output:
        f"{RESULTS}/datasets/configurations.csv",
    log:
        f"{LOGS}/datasets/configurations.log",
    benchmark:
        f"{BENCHMARKS}/datasets/configurations.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        settings=settings_json("fences", "datasets"),
        parts=",".join(PARTS),
    shell:
        "feeder datasets configurations --settings '{params.settings}' --parts '{params.parts}'"
        " --out {output} > {log} 2>&1"


rule datasets_build:
    """Merge every simulation file and the part features into dataset.npz (docs/data.md)."""
    input:
        code("datasets"),
        configurations=f"{RESULTS}/datasets/configurations.csv",
        sims=[sim_path(p, c) for p, c in zip(CONFIGS["part"], CONFIGS["config_id"])],
        features=expand(f"{RESULTS}/features/{{part}}.json", part=sorted(set(CONFIGS["part"]))),
        parts=expand("{dir}/{part}.stl", dir=config["parts"]["dir"], part=sorted(set(CONFIGS["part"]))),
    output:
        DATASET,
    log:
        f"{LOGS}/datasets/build.log",
    benchmark:
        f"{BENCHMARKS}/datasets/build.tsv"
    conda:
        "../envs/feeder.yaml"
    threads: config["threads"]["datasets_build"]
    params:
        settings=settings_json(
            "sim.min_ok_mass",
            "sim.preset",
            "sim.yaw_sampling",
            "sim.drops",
            "labels",
            "datasets",
            "scene",
            "parts.units",
        ),
        parts_dir=lambda w, input: os.path.dirname(input.parts[0]),
        features_dir=lambda w, input: os.path.dirname(input.features[0]),
        sim_dir=lambda w, input: os.path.dirname(os.path.dirname(input.sims[0])),  # <results>/sim
    shell:
        "feeder datasets build --configurations {input.configurations} --features-dir {params.features_dir}"
        " --sim-dir {params.sim_dir} --parts-dir {params.parts_dir} --settings '{params.settings}' --workers {threads}"
        " --out {output}"
        " > {log} 2>&1"


rule datasets_table4:
    """Table 4: samples and unique parts per dataset, exclusions counted."""
    input:
        code("datasets"),
        dataset=DATASET,
    output:
        csv=report(f"{RESULTS}/tables/table4.csv", caption="../report/table4.rst", category="Datasets"),
        md=report(f"{RESULTS}/tables/table4.md", caption="../report/table4.rst", category="Datasets"),
    log:
        f"{LOGS}/datasets/table4.log",
    benchmark:
        f"{BENCHMARKS}/datasets/table4.tsv"
    conda:
        "../envs/feeder.yaml"
    shell:
        "feeder datasets table4 --dataset {input.dataset} --out-csv {output.csv} --out-md {output.md} > {log} 2>&1"


rule datasets_convergence:
    """The convergence tables and the data of Figs. 4, 5, 9 and the DKW view."""
    input:
        code("datasets"),
        dataset=DATASET,
    output:
        dkw_csv=report(
            f"{RESULTS}/tables/convergence_dkw.csv", caption="../report/convergence_dkw_table.rst", category="Datasets"
        ),
        js_csv=report(
            f"{RESULTS}/tables/convergence_js.csv", caption="../report/convergence_js.rst", category="Datasets"
        ),
        fig4=f"{RESULTS}/figdata/fig4_js_vs_drops.csv",
        fig5=f"{RESULTS}/figdata/fig5_js_hist.npz",
        fig9=f"{RESULTS}/figdata/fig9_example_pmfs.npz",
        dkw=f"{RESULTS}/figdata/convergence_dkw.npz",
    log:
        f"{LOGS}/datasets/convergence.log",
    benchmark:
        f"{BENCHMARKS}/datasets/convergence.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        settings=settings_json("labels", "datasets"),
    shell:
        "feeder datasets convergence --dataset {input.dataset} --settings '{params.settings}'"
        " --dkw-csv {output.dkw_csv} --js-csv {output.js_csv} --fig4-data {output.fig4}"
        " --fig5-data {output.fig5} --fig9-data {output.fig9} --dkw-data {output.dkw} > {log} 2>&1"


rule audit:
    """One part's audit drops, simulated beside its grid or adaptive labels (feeder audit run)."""
    input:
        code("audit"),
        part=lambda wildcards: f"{config['parts']['dir']}/{wildcards.part}.stl",
        sims=lambda wildcards: [
            sim_path(p, c) for p, c in zip(CONFIGS["part"], CONFIGS["config_id"]) if p == wildcards.part
        ],
    output:
        f"{RESULTS}/audit/{{part}}.csv",
    log:
        f"{LOGS}/audit/{{part}}.log",
    benchmark:
        f"{BENCHMARKS}/audit/{{part}}.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        audits=config["sim"]["adaptive_target"]["audits"],
        units=config["parts"]["units"],
    shell:
        "feeder audit run --part {input.part} --sims {input.sims} --audits {params.audits} --units {params.units}"
        " --out {output} > {log} 2>&1"


rule label_errors:
    """Every label's error estimate from its simulation file and audit drops (feeder audit table)."""
    input:
        code("audit"),
        configurations=f"{RESULTS}/datasets/configurations.csv",
        sims=[sim_path(p, c) for p, c in zip(CONFIGS["part"], CONFIGS["config_id"])],
        audits=expand(f"{RESULTS}/audit/{{part}}.csv", part=AUDIT_PARTS),
    output:
        csv=report(
            f"{RESULTS}/tables/label_error_estimate.csv",
            caption="../report/label_error_estimate.rst",
            category="Datasets",
        ),
        summary=report(
            f"{RESULTS}/tables/label_error_estimate_summary.csv",
            caption="../report/label_error_estimate_summary.rst",
            category="Datasets",
        ),
    log:
        f"{LOGS}/audit/table.log",
    benchmark:
        f"{BENCHMARKS}/audit/table.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        settings=settings_json("labels", "sim.min_ok_mass", "sim.adaptive_target"),
        sim_dir=lambda wildcards, input: os.path.dirname(os.path.dirname(input.sims[0])),  # <results>/sim
    shell:
        "feeder audit table --configurations {input.configurations} --sim-dir {params.sim_dir}"
        " --audits {input.audits} --settings '{params.settings}'"
        " --out-csv {output.csv} --out-summary {output.summary} > {log} 2>&1"
