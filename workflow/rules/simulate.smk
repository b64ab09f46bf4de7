# Simulation stage: one job per part x fence configuration and Table 1 from the scene settings.
# Uses config, code and sim_settings from common.smk. Outputs:
#   results/sim/{part}/{fence}.npz                  (docs/data.md)
#   results/tables/table1.csv                       (every physical parameter of the scene)


rule simulate:
    """Drops of one part through one fence configuration (feeder simulate)."""
    input:
        code("simulate"),
        part=lambda wildcards: f"{config['parts']['dir']}/{wildcards.part}.stl",
    output:
        f"{RESULTS}/sim/{{part}}/{{fence}}.npz",
    log:
        f"{LOGS}/simulate/{{part}}/{{fence}}.log",
    benchmark:
        f"{BENCHMARKS}/simulate/{{part}}/{{fence}}.tsv"
    wildcard_constraints:
        part=r"[A-Za-z0-9-]+",
        fence=r"[a-z0-9.]+_[a-z0-9.]+",
    conda:
        "../envs/feeder.yaml"
    params:
        settings=sim_settings(),
        preset=config["sim"]["preset"],
        drops=config["sim"]["drops"],
        seed=config["sim"]["base_seed"],
        units=config["parts"]["units"],
        yaw_sampling=config["sim"]["yaw_sampling"],
        design=design_options(),
        loc1=fence_location(0),
        loc2=fence_location(1),
    shell:
        "feeder simulate --part {input.part} --loc1 {params.loc1} --loc2 {params.loc2}"
        " --drops {params.drops} --seed {params.seed} --yaw-sampling {params.yaw_sampling} {params.design}"
        " --preset {params.preset} --units {params.units}"
        " --settings '{params.settings}' --out {output} > {log} 2>&1"


rule scene_table:
    """Table 1: every physical parameter of the simulated scene and the simulation presets."""
    input:
        code("scene-table"),
    output:
        report(f"{RESULTS}/tables/table1.csv", caption="../report/table1.rst", category="Simulation"),
    log:
        f"{LOGS}/scene_table/table1.log",
    benchmark:
        f"{BENCHMARKS}/scene_table/table1.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        settings=settings_json("scene", "sim.presets"),
    shell:
        "feeder scene-table --settings '{params.settings}' --out {output} > {log} 2>&1"
