# Simulation stage: one job per part x fence configuration, Table 1 from the scene settings, and
# the accuracy-against-time benchmark of the simulation settings. Uses config, pkg and
# sim_path-style paths from common.smk. Outputs:
#   results/sim/{part}/{fence}.npz                  (docs/data.md)
#   results/tables/table1.csv                       (every physical parameter of the scene)
#   results/tables/jam_rates.csv                    (ok and jam rates of each fence angle: why the grid leaves some out)
#   results/tables/sim_accuracy_vs_time.csv, results/figures/sim_accuracy_vs_time.png (the figure
#   is drawn from the table by its own job, feeder figure sim_accuracy_vs_time; uses figure_code)
#   results/tables/yaw_sampling.csv, results/figures/yaw_sampling.png (drops needed per yaw design)
#   results/tables/sim_cost.csv, sim_cost_sample.csv, results/figures/sim_cost.png (the stage's
#   projected cost, measured on a sample of its own jobs)
SIM_MODULES = ("sim", "scene", "fences", "geometry")


rule simulate:
    """Drops of one part through one fence configuration (feeder simulate)."""
    input:
        pkg(*SIM_MODULES),
        part=lambda wildcards: f"{config['parts']['dir']}/{wildcards.part}.stl",
    output:
        "results/sim/{part}/{fence}.npz",
    wildcard_constraints:
        part=r"[A-Za-z0-9-]+",
        fence=r"[a-z0-9.]+_[a-z0-9.]+",
    params:
        settings=sim_settings(),
        preset=config["sim"]["preset"],
        drops=config["sim"]["drops"],
        seed=config["sim"]["base_seed"],
        yaw_sampling=config["sim"]["yaw_sampling"],
        loc1=fence_location(0),
        loc2=fence_location(1),
    log:
        "logs/simulate/{part}/{fence}.log",
    benchmark:
        "benchmarks/simulate/{part}/{fence}.tsv"
    conda:
        "../envs/feeder.yaml"
    shell:
        "feeder simulate --part {input.part} --loc1 {params.loc1} --loc2 {params.loc2}"
        " --drops {params.drops} --seed {params.seed} --yaw-sampling {params.yaw_sampling} --preset {params.preset}"
        " --settings '{params.settings}' --out {output} > {log} 2>&1"


rule scene_table:
    """Table 1: every physical parameter of the simulated scene and the simulation presets."""
    input:
        pkg("scene"),
    output:
        report("results/tables/table1.csv", caption="../report/table1.rst", category="Simulation"),
    params:
        settings=settings_json("scene", "sim.presets"),
    log:
        "logs/scene_table/table1.log",
    benchmark:
        "benchmarks/scene_table/table1.tsv"
    conda:
        "../envs/feeder.yaml"
    shell:
        "feeder scene-table --settings '{params.settings}' --out {output} > {log} 2>&1"


rule bench_sim:
    """Accuracy against CPU time of the simulation settings over a fixed panel (feeder bench-sim)."""
    input:
        pkg("bench", "sim_shapes", "labels", *SIM_MODULES),
    output:
        report("results/tables/sim_accuracy_vs_time.csv", caption="../report/sim_accuracy_vs_time_table.rst", category="Simulation"),
    params:
        settings=settings_json("scene", "sim.presets", "sim.bench", "labels"),
    threads: config["sim"]["bench"]["workers"]
    log:
        "logs/bench_sim/bench_sim.log",
    benchmark:
        "benchmarks/bench_sim/bench_sim.tsv"
    conda:
        "../envs/feeder.yaml"
    shell:
        "feeder bench-sim --settings '{params.settings}' --out-csv {output} > {log} 2>&1"


rule draw_sim_accuracy_vs_time:
    """The accuracy-against-time figure drawn from the benchmark table."""
    input:
        figure_code("sim_accuracy_vs_time"),
        data="results/tables/sim_accuracy_vs_time.csv",
    output:
        report(
            "results/figures/sim_accuracy_vs_time.png",
            caption="../report/sim_accuracy_vs_time.rst",
            category="Simulation",
        ),
    params:
        reference=config["sim"]["bench"]["reference"],
    log:
        "logs/figures/sim_accuracy_vs_time.log",
    benchmark:
        "benchmarks/figures/sim_accuracy_vs_time.tsv"
    conda:
        "../envs/feeder.yaml"
    shell:
        "feeder figure sim_accuracy_vs_time --data {input.data} --reference {params.reference} --out {output} > {log} 2>&1"


rule bench_jams:
    """Ok and jam rates of each fence angle of the survey, alone at each location (feeder bench-jams)."""
    input:
        pkg("jams", *SIM_MODULES),
        parts=expand("{dir}/{part}.stl", dir=config["parts"]["dir"], part=config["sim"]["jam_survey"]["parts"]),
    output:
        report("results/tables/jam_rates.csv", caption="../report/jam_rates.rst", category="Simulation"),
    params:
        settings=settings_json("scene", "sim.presets", "sim.jam_survey", "sim.base_seed", "parts.dir"),
    threads: config["sim"]["jam_survey"]["workers"]
    log:
        "logs/bench_jams/bench_jams.log",
    benchmark:
        "benchmarks/bench_jams/bench_jams.tsv"
    conda:
        "../envs/feeder.yaml"
    shell:
        "feeder bench-jams --settings '{params.settings}' --out-csv {output} > {log} 2>&1"


rule draw_jam_rates:
    """The jam-survey figure drawn from its table."""
    input:
        figure_code("jam_rates"),
        data="results/tables/jam_rates.csv",
    output:
        report("results/figures/jam_rates.png", caption="../report/jam_rates_figure.rst", category="Simulation"),
    log:
        "logs/figures/jam_rates.log",
    benchmark:
        "benchmarks/figures/jam_rates.tsv"
    conda:
        "../envs/feeder.yaml"
    shell:
        "feeder figure jam_rates --data {input.data} --out {output} > {log} 2>&1"


rule bench_yaws:
    """Distance to a large independent reference against drops, per initial-yaw design (feeder bench-yaws)."""
    input:
        pkg("bench_yaws", "bench", "sim_shapes", "labels", *SIM_MODULES),
    output:
        report("results/tables/yaw_sampling.csv", caption="../report/yaw_sampling_table.rst", category="Simulation"),
    params:
        settings=settings_json("scene", "sim.presets", "sim.bench", "sim.yaw_bench", "labels"),
    threads: config["sim"]["yaw_bench"]["workers"]
    log:
        "logs/bench_yaws/bench_yaws.log",
    benchmark:
        "benchmarks/bench_yaws/bench_yaws.tsv"
    conda:
        "../envs/feeder.yaml"
    shell:
        "feeder bench-yaws --settings '{params.settings}' --out-csv {output} > {log} 2>&1"


rule draw_yaw_sampling:
    """The drops-needed figure drawn from its table."""
    input:
        figure_code("yaw_sampling"),
        data="results/tables/yaw_sampling.csv",
    output:
        report("results/figures/yaw_sampling.png", caption="../report/yaw_sampling.rst", category="Simulation"),
    log:
        "logs/figures/yaw_sampling.log",
    benchmark:
        "benchmarks/figures/yaw_sampling.tsv"
    conda:
        "../envs/feeder.yaml"
    shell:
        "feeder figure yaw_sampling --data {input.data} --out {output} > {log} 2>&1"


rule bench_cost:
    """The simulation stage's CPU and wall time projected from a sample of its own jobs (feeder bench-cost)."""
    input:
        pkg("bench_cost", "bench", "datasets", "labels", "parts", *SIM_MODULES),
        parts=expand("{dir}/{part}.stl", dir=config["parts"]["dir"], part=PARTS),
    output:
        sample=report("results/tables/sim_cost_sample.csv", caption="../report/sim_cost_sample.rst", category="Cost"),
        summary=report("results/tables/sim_cost.csv", caption="../report/sim_cost.rst", category="Cost"),
    params:
        settings=settings_json("parts.dir", "parts.include", "fences", "datasets", "scene", "sim.preset", "sim.presets",
                               "sim.drops", "sim.base_seed", "sim.yaw_sampling", "sim.cost_bench"),
    threads: config["sim"]["cost_bench"]["workers"]
    log:
        "logs/bench_cost/bench_cost.log",
    benchmark:
        "benchmarks/bench_cost/bench_cost.tsv"
    conda:
        "../envs/feeder.yaml"
    shell:
        "feeder bench-cost --settings '{params.settings}' --out-csv {output.sample} --out-summary {output.summary} > {log} 2>&1"


rule draw_sim_cost:
    """The per-part cost figure drawn from the sampled jobs."""
    input:
        figure_code("sim_cost"),
        data="results/tables/sim_cost_sample.csv",
    output:
        report("results/figures/sim_cost.png", caption="../report/sim_cost_figure.rst", category="Cost"),
    log:
        "logs/figures/sim_cost.log",
    benchmark:
        "benchmarks/figures/sim_cost.tsv"
    conda:
        "../envs/feeder.yaml"
    shell:
        "feeder figure sim_cost --data {input.data} --out {output} > {log} 2>&1"
