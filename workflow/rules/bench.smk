# Benchmarks of the simulation itself: what accuracy costs in time (bench_sim), how many drops
# each initial-yaw design needs (bench_yaws), which fence angles jam (bench_jams), and what the
# simulation stage will cost (bench_cost). Not part of the study's default target: `make bench`
# (snakemake bench) rebuilds them. Outputs:
#   results/tables/sim_accuracy_vs_time.csv   (+ figure)  settings against CPU time
#   results/tables/yaw_sampling.csv           (+ figure)  distance to a large reference against drops
#   results/tables/jam_rates.csv              (+ figure)  ok and jam rates of each fence angle
#   results/tables/sim_cost.csv, sim_cost_sample.csv (+ figure)  the stage's projected cost
#   results/tables/label_emulation*.csv       (+ figure)  emulated i.i.d. drops against real ones
#   results/tables/design_error_estimate*.csv            the label error estimate's coverage (emulated)
#   results/tables/contact_model.csv          (+ figure)  the belt footprint: pieces against pads
#   results/tables/contact_decomposition.csv  (+ figure)  each contact model under other convex decompositions
#   results/tables/step_cost.csv              (+ figure)  CPU of one step against a bare one-box world
#   results/tables/physics_sensitivity.csv    (+ figure)  how far the labels move with each physical parameter
#   results/tables/frontier_known.csv         (+ figure)  every answer for a known part at a new angle, and its cost

from feeder.bench.emulation import entries as emulation_bench_entries, run_settings as emulation_run_settings
from feeder.bench.predict import DEFAULT_PARTS as PREDICT_BENCH_DEFAULT_PARTS

BENCH_TARGETS = [
    f"{RESULTS}/tables/sim_accuracy_vs_time.csv",
    f"{RESULTS}/figures/sim_accuracy_vs_time.png",
    f"{RESULTS}/tables/jam_rates.csv",
    f"{RESULTS}/figures/jam_rates.png",
    f"{RESULTS}/tables/yaw_sampling.csv",
    f"{RESULTS}/figures/yaw_sampling.png",
    f"{RESULTS}/tables/sim_cost.csv",
    f"{RESULTS}/figures/sim_cost.png",
    f"{RESULTS}/tables/label_designs.csv",
    f"{RESULTS}/tables/label_designs_summary.csv",
    f"{RESULTS}/figures/label_designs.png",
    f"{RESULTS}/tables/design_error_estimate.csv",
    f"{RESULTS}/tables/design_error_estimate_summary.csv",
    f"{RESULTS}/tables/frontier.csv",
    f"{RESULTS}/tables/frontier_known.csv",
    f"{RESULTS}/figures/frontier_known.png",
    f"{RESULTS}/tables/mirror_locations.csv",
    f"{RESULTS}/figures/frontier.png",
    f"{RESULTS}/tables/label_emulation.csv",
    f"{RESULTS}/tables/label_emulation_summary.csv",
    f"{RESULTS}/figures/label_emulation.png",
    f"{RESULTS}/tables/contact_model.csv",
    f"{RESULTS}/figures/contact_model.png",
    f"{RESULTS}/tables/contact_decomposition.csv",
    f"{RESULTS}/figures/contact_decomposition.png",
    f"{RESULTS}/tables/step_cost.csv",
    f"{RESULTS}/figures/step_cost.png",
    f"{RESULTS}/tables/physics_sensitivity.csv",
    f"{RESULTS}/figures/physics_sensitivity.png",
]
# the design bench's configurations: one simulation job each (resumable), raw data kept, in a
# directory named by the preset and the reference's resolution, so a smaller run (smoke) never
# overwrites the committed references
DESIGN_KEYS = [e["key"] for e in design_bench_entries(config)]
DESIGN_DIR = "{results}/bench/designs/{preset}-{reference_yaws}".format(
    results=RESULTS, **config["sim"]["design_bench"]
)
# the emulation bench's configurations: one simulation job each, raw data kept; a job's settings
# hold its own configuration only, so adding one to the list reruns no other
EMULATION_KEYS = [e["key"] for e in emulation_bench_entries(config)]
# the parts bench_predict times: its default panel, those in use (else the first part in use)
PREDICT_BENCH_PARTS = [p for p in PREDICT_BENCH_DEFAULT_PARTS if p in PARTS] or PARTS[:1]
# the contact bench picks its parts from the whole library (those with many convex pieces)
# candidates of the contact bench (those with sim.contact_bench.min_pieces pieces): the library's parts
# but the wider library's (contact_model.csv predates it)
CONTACT_PARTS = protocol_parts(config, list_parts(config["parts"]["dir"], "all"))
EMULATION_DIR = "{results}/bench/emulation/{preset}".format(results=RESULTS, **config["sim"]["emulation_bench"])


rule bench:
    """Every benchmark table and figure (not part of the default target)."""
    input:
        BENCH_TARGETS,


rule bench_sim:
    """Accuracy against CPU time of the simulation settings over a fixed panel (feeder bench-sim)."""
    input:
        code("bench-sim"),
    output:
        report(
            f"{RESULTS}/tables/sim_accuracy_vs_time.csv",
            caption="../report/sim_accuracy_vs_time_table.rst",
            category="Simulation",
        ),
    log:
        f"{LOGS}/bench_sim/bench_sim.log",
    benchmark:
        f"{BENCHMARKS}/bench_sim/bench_sim.tsv"
    conda:
        "../envs/feeder.yaml"
    threads: config["sim"]["bench"]["workers"]
    params:
        settings=settings_json("scene", "sim.presets", "sim.bench", "labels"),
    shell:
        "feeder bench-sim --settings '{params.settings}' --out-csv {output} > {log} 2>&1"


rule bench_jams:
    """Ok and jam rates of each fence angle of the survey, alone at each location (feeder bench-jams)."""
    input:
        code("bench-jams"),
        parts=expand("{dir}/{part}.stl", dir=config["parts"]["dir"], part=config["sim"]["jam_survey"]["parts"]),
    output:
        report(f"{RESULTS}/tables/jam_rates.csv", caption="../report/jam_rates.rst", category="Simulation"),
    log:
        f"{LOGS}/bench_jams/bench_jams.log",
    benchmark:
        f"{BENCHMARKS}/bench_jams/bench_jams.tsv"
    conda:
        "../envs/feeder.yaml"
    threads: config["sim"]["jam_survey"]["workers"]
    params:
        settings=settings_json("scene", "sim.presets", "sim.jam_survey", "sim.base_seed", "parts.dir"),
    shell:
        "feeder bench-jams --settings '{params.settings}' --out-csv {output} > {log} 2>&1"


rule bench_contact:
    """The belt footprint, each convex piece against pads, the same drops paired (feeder bench-contact)."""
    input:
        code("bench-contact"),
        parts=expand("{dir}/{part}.stl", dir=config["parts"]["dir"], part=CONTACT_PARTS),
    output:
        table=report(
            f"{RESULTS}/tables/contact_model.csv", caption="../report/contact_model.rst", category="Simulation"
        ),
        raw=f"{RESULTS}/bench/contact/contact_drops.csv",
    log:
        f"{LOGS}/bench_contact/bench_contact.log",
    benchmark:
        f"{BENCHMARKS}/bench_contact/bench_contact.tsv"
    conda:
        "../envs/feeder.yaml"
    threads: config["sim"]["contact_bench"]["workers"]
    params:
        settings=settings_json("scene", "sim.presets", "sim.contact_bench", "sim.base_seed", "parts.dir"),
        parts=",".join(CONTACT_PARTS),
    shell:
        "feeder bench-contact --settings '{params.settings}' --parts '{params.parts}'"
        " --out-csv {output.table} --out-raw {output.raw} > {log} 2>&1"


rule bench_decomposition:
    """Each contact model's drops under other convex decompositions of a part, kept raw (feeder bench-decomposition)."""
    input:
        code("bench-decomposition"),
        parts=expand(
            "{dir}/{part}.stl", dir=config["parts"]["dir"], part=list(config["sim"]["decomposition_bench"]["parts"])
        ),
    output:
        raw=f"{RESULTS}/bench/decomposition/decomposition_drops.csv",
    log:
        f"{LOGS}/bench_decomposition/bench_decomposition.log",
    benchmark:
        f"{BENCHMARKS}/bench_decomposition/bench_decomposition.tsv"
    conda:
        "../envs/feeder.yaml"
    threads: config["sim"]["decomposition_bench"]["workers"]
    params:
        settings=settings_json("scene", "sim.presets", "sim.decomposition_bench", "sim.base_seed", "parts.dir"),
    shell:
        "feeder bench-decomposition --settings '{params.settings}' --out-raw {output.raw} > {log} 2>&1"


rule bench_decomposition_table:
    """The decomposition test's comparisons, floors and verdicts from the raw drops, simulating nothing (feeder bench-decomposition-table)."""
    input:
        code("bench-decomposition-table"),
        raw=f"{RESULTS}/bench/decomposition/decomposition_drops.csv",
    output:
        table=report(
            f"{RESULTS}/tables/contact_decomposition.csv",
            caption="../report/contact_decomposition.rst",
            category="Simulation",
        ),
    log:
        f"{LOGS}/bench_decomposition/bench_decomposition_table.log",
    benchmark:
        f"{BENCHMARKS}/bench_decomposition/bench_decomposition_table.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        settings=settings_json("sim.decomposition_bench", "labels.bins", "labels.sigma_bins"),
    shell:
        "feeder bench-decomposition-table --settings '{params.settings}'"
        " --raw {input.raw} --out-csv {output.table} > {log} 2>&1"


rule bench_physics:
    """Each configuration's drops under the default scene and one physical factor at a time, kept raw (feeder bench-physics)."""
    input:
        code("bench-physics"),
        parts=expand(
            "{dir}/{part}.stl",
            dir=config["parts"]["dir"],
            part=sorted({p for p, _ in config["sim"]["physics_bench"]["configurations"]}),
        ),
    output:
        raw=f"{RESULTS}/bench/physics/physics_drops.csv",
    log:
        f"{LOGS}/bench_physics/bench_physics.log",
    benchmark:
        f"{BENCHMARKS}/bench_physics/bench_physics.tsv"
    conda:
        "../envs/feeder.yaml"
    threads: config["sim"]["physics_bench"]["workers"]
    params:
        settings=settings_json("scene", "sim.presets", "sim.physics_bench", "parts.dir"),
    shell:
        "feeder bench-physics --settings '{params.settings}' --out-raw {output.raw} > {log} 2>&1"


rule bench_physics_table:
    """The label shift of each physical factor beside the floor and the models' errors, from the raw drops (feeder bench-physics-table).
    The models' errors are read from the committed tables named in sim.physics_bench.model_errors, not
    declared as inputs: the bench never rebuilds the study's models."""
    input:
        code("bench-physics-table"),
        raw=f"{RESULTS}/bench/physics/physics_drops.csv",
    output:
        table=report(
            f"{RESULTS}/tables/physics_sensitivity.csv",
            caption="../report/physics_sensitivity.rst",
            category="Simulation",
        ),
    log:
        f"{LOGS}/bench_physics/bench_physics_table.log",
    benchmark:
        f"{BENCHMARKS}/bench_physics/bench_physics_table.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        settings=settings_json("sim.physics_bench", "labels.bins", "labels.sigma_bins"),
    shell:
        "feeder bench-physics-table --settings '{params.settings}'"
        " --raw {input.raw} --out-csv {output.table} > {log} 2>&1"


rule bench_step:
    """CPU of one simulation step in the study's scene against a bare one-box world (feeder bench-step)."""
    input:
        code("bench-step"),
        parts=expand("{dir}/{part}.stl", dir=config["parts"]["dir"], part=config["sim"]["step_bench"]["parts"]),
    output:
        table=report(f"{RESULTS}/tables/step_cost.csv", caption="../report/step_cost.rst", category="Simulation"),
        raw=f"{RESULTS}/bench/step/step_calls.csv",
    log:
        f"{LOGS}/bench_step/bench_step.log",
    benchmark:
        f"{BENCHMARKS}/bench_step/bench_step.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        settings=settings_json("scene", "sim.presets", "sim.step_bench", "sim.base_seed", "parts.dir"),
    shell:
        "feeder bench-step --settings '{params.settings}' --out-csv {output.table} --out-raw {output.raw} > {log} 2>&1"


rule bench_yaws:
    """Distance to a large independent reference against drops, per initial-yaw design (feeder bench-yaws)."""
    input:
        code("bench-yaws"),
    output:
        report(f"{RESULTS}/tables/yaw_sampling.csv", caption="../report/yaw_sampling_table.rst", category="Simulation"),
    log:
        f"{LOGS}/bench_yaws/bench_yaws.log",
    benchmark:
        f"{BENCHMARKS}/bench_yaws/bench_yaws.tsv"
    conda:
        "../envs/feeder.yaml"
    threads: config["sim"]["yaw_bench"]["workers"]
    params:
        settings=settings_json("scene", "sim.presets", "sim.bench", "sim.yaw_bench", "labels"),
    shell:
        "feeder bench-yaws --settings '{params.settings}' --out-csv {output} > {log} 2>&1"


rule bench_cost:
    """The simulation stage's CPU and wall time projected from a sample of its own jobs (feeder bench-cost)."""
    input:
        code("bench-cost"),
        parts=expand("{dir}/{part}.stl", dir=config["parts"]["dir"], part=PARTS),
    output:
        sample=report(f"{RESULTS}/tables/sim_cost_sample.csv", caption="../report/sim_cost_sample.rst", category="Cost"),
        summary=report(f"{RESULTS}/tables/sim_cost.csv", caption="../report/sim_cost.rst", category="Cost"),
    log:
        f"{LOGS}/bench_cost/bench_cost.log",
    benchmark:
        f"{BENCHMARKS}/bench_cost/bench_cost.tsv"
    conda:
        "../envs/feeder.yaml"
    threads: config["sim"]["cost_bench"]["workers"]
    params:
        settings=settings_json(
            "parts.dir",
            "parts.include",
            "parts.exclude",
            "fences",
            "datasets",
            "scene",
            "sim.preset",
            "sim.presets",
            "sim.drops",
            "sim.base_seed",
            "sim.yaw_sampling",
            "sim.adaptive",
            "sim.cost_bench",
        ),
    shell:
        "feeder bench-cost --settings '{params.settings}' --out-csv {output.sample} --out-summary {output.summary} > {log} 2>&1"


rule bench_reference:
    """The design bench's dense reference of one configuration, and its paired drops (feeder bench-reference run)."""
    input:
        code("bench-reference"),
    output:
        f"{DESIGN_DIR}/reference/{{key}}.npz",
    log:
        f"{LOGS}/bench_reference/{{key}}.log",
    benchmark:
        f"{BENCHMARKS}/bench_reference/{{key}}.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        settings=settings_json("scene", "parts.dir", "sim.presets", "sim.bench", "sim.design_bench"),
    shell:
        "feeder bench-reference run --key {wildcards.key} --settings '{params.settings}' --out {output} > {log} 2>&1"


rule bench_designs_run:
    """The adaptive design of one configuration at every budget (feeder bench-designs run)."""
    input:
        code("bench-designs"),
    output:
        f"{DESIGN_DIR}/adaptive/{{key}}.npz",
    log:
        f"{LOGS}/bench_designs/{{key}}.log",
    benchmark:
        f"{BENCHMARKS}/bench_designs/{{key}}.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        settings=settings_json("scene", "parts.dir", "sim.presets", "sim.bench", "sim.design_bench", "sim.adaptive"),
    shell:
        "feeder bench-designs run --key {wildcards.key} --settings '{params.settings}' --out {output} > {log} 2>&1"


rule bench_designs:
    """Every initial-yaw design's label against the dense reference, and its cost (feeder bench-designs table)."""
    input:
        code("bench-designs"),
        references=expand(f"{DESIGN_DIR}/reference/{{key}}.npz", key=DESIGN_KEYS),
        adaptive=expand(f"{DESIGN_DIR}/adaptive/{{key}}.npz", key=DESIGN_KEYS),
    output:
        rows=report(f"{RESULTS}/tables/label_designs.csv", caption="../report/label_designs.rst", category="Simulation"),
        summary=report(
            f"{RESULTS}/tables/label_designs_summary.csv",
            caption="../report/label_designs_summary.rst",
            category="Simulation",
        ),
    log:
        f"{LOGS}/bench_designs/table.log",
    benchmark:
        f"{BENCHMARKS}/bench_designs/table.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        settings=settings_json(
            "labels", "sim.design_bench", "sim.adaptive", "sim.min_ok_mass", "sim.drops", "sim.yaw_sampling"
        ),
    shell:
        "feeder bench-designs table --references {input.references} --adaptive {input.adaptive}"
        " --settings '{params.settings}' --out-csv {output.rows} --out-summary {output.summary} > {log} 2>&1"


rule bench_errest:
    """Does each label's error estimate cover its error; what the targeted design costs (feeder bench-errest)."""
    input:
        code("bench-errest"),
        references=expand(f"{DESIGN_DIR}/reference/{{key}}.npz", key=DESIGN_KEYS),
    output:
        rows=report(
            f"{RESULTS}/tables/design_error_estimate.csv",
            caption="../report/design_error_estimate.rst",
            category="Simulation",
        ),
        summary=report(
            f"{RESULTS}/tables/design_error_estimate_summary.csv",
            caption="../report/design_error_estimate_summary.rst",
            category="Simulation",
        ),
    log:
        f"{LOGS}/bench_errest/table.log",
    benchmark:
        f"{BENCHMARKS}/bench_errest/table.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        settings=settings_json(
            "labels",
            "sim.design_bench",
            "sim.errest_bench",
            "sim.adaptive",
            "sim.adaptive_target",
            "sim.min_ok_mass",
            "sim.drops",
        ),
    shell:
        "feeder bench-errest --references {input.references} --settings '{params.settings}'"
        " --out-csv {output.rows} --out-summary {output.summary} > {log} 2>&1"


rule bench_mirror:
    """A fence at Location 2 against its mirror image at Location 1, drop by drop (feeder bench-mirror)."""
    input:
        code("bench-mirror"),
        catalog=f"{config['parts']['dir']}/catalog.csv",
    output:
        raw=f"{RESULTS}/bench/mirror/mirror_drops.csv",
        csv=report(f"{RESULTS}/tables/mirror_locations.csv", caption="../report/mirror_locations.rst", category="Cost"),
    log:
        f"{LOGS}/bench_mirror/bench.log",
    benchmark:
        f"{BENCHMARKS}/bench_mirror/bench.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        settings=settings_json("scene", "labels", "parts", "sim.mirror_bench", "sim.presets", "sim.base_seed"),
    shell:
        "feeder bench-mirror --settings '{params.settings}' --out-raw {output.raw} --out-csv {output.csv} > {log} 2>&1"


# the frontier's predictors: the analytic PMF and those of sim.frontier_bench.models the run ships
FRONTIER_MODELS = [m for m in config["sim"]["frontier_bench"]["models"] if m == "analytic" or m in SHIPPED]


rule bench_frontier:
    """Every predictor and simulation budget: its error against the dense labels, its cost (feeder bench-frontier)."""
    input:
        code("bench-frontier"),
        references=expand(f"{DESIGN_DIR}/reference/{{key}}.npz", key=DESIGN_KEYS),
        dataset=DATASET,
        models=[f"{EXPORT_DIR}/{m}" for m in FRONTIER_MODELS if m != "analytic"],
    output:
        raw=f"{RESULTS}/bench/frontier/frontier_answers.csv",
        csv=report(f"{RESULTS}/tables/frontier.csv", caption="../report/frontier.rst", category="Cost"),
    log:
        f"{LOGS}/bench_frontier/table.log",
    benchmark:
        f"{BENCHMARKS}/bench_frontier/table.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        settings=settings_json(
            "scene",
            "labels",
            "parts",
            "sim.frontier_bench",
            "sim.adaptive",
            "sim.bench",
            "sim.min_ok_mass",
            "models.export_dir",
        ),
        models=" ".join(FRONTIER_MODELS),
    shell:
        "feeder bench-frontier --references {input.references} --dataset {input.dataset} --models {params.models}"
        " --settings '{params.settings}' --out-raw {output.raw} --out-csv {output.csv}"
        " > {log} 2>&1"


# the known-part frontier's shipped models: those of sim.frontier_known.models the run ships
FRONTIER_KNOWN_MODELS = [m for m in config["sim"]["frontier_known"]["models"] if m in SHIPPED]


rule bench_frontier_known:
    """Every predictor (the structured one included) and simulation budget on the dataset's Test
    configurations: its error against their labels, its cost (feeder bench-frontier-known). Keeps its
    fit and simulation files in results/bench/frontier_known/ and reuses them on a rerun."""
    input:
        code("bench-frontier-known"),
        dataset=DATASET,
        sims=[sim_path(p, c) for p, c in zip(CONFIGS["part"], CONFIGS["config_id"])],
        parts=expand("{dir}/{part}.stl", dir=config["parts"]["dir"], part=sorted(set(CONFIGS["part"]))),
        features=expand(f"{RESULTS}/features/{{part}}.json", part=sorted(set(CONFIGS["part"]))),
        candidates=f"{RESULTS}/datasets/structured_candidates.npz",
        models=[f"{EXPORT_DIR}/{m}" for m in FRONTIER_KNOWN_MODELS],
    output:
        raw=f"{RESULTS}/bench/frontier_known/answers.csv",
        csv=report(f"{RESULTS}/tables/frontier_known.csv", caption="../report/frontier_known.rst", category="Cost"),
    log:
        f"{LOGS}/bench_frontier_known/table.log",
    benchmark:
        f"{BENCHMARKS}/bench_frontier_known/table.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        settings=settings_json(
            "scene",
            "labels",
            "parts",
            "sim.frontier_known",
            "sim.adaptive",
            "sim.presets",
            "sim.preset",
            "sim.base_seed",
            "models.export_dir",
        ),
        structured=resolved_yaml("structured", STRUCTURED_OVERRIDES, drop=("analytic_scenes",)),  # its gates choose the gated neighbour
        overrides=" ".join(shlex.quote(o) for o in STRUCTURED_OVERRIDES),
        models=" ".join(FRONTIER_KNOWN_MODELS),
    shell:
        "feeder bench-frontier-known --dataset {input.dataset} --sim-dir $(dirname $(dirname {input.sims[0]}))"
        " --parts-dir $(dirname {input.parts[0]}) --features-dir $(dirname {input.features[0]})"
        " --cache {input.candidates} --work-dir $(dirname {output.raw}) --models {params.models}"
        " --settings '{params.settings}' --out-raw {output.raw} --out-csv {output.csv} {params.overrides}"
        " > {log} 2>&1"


rule bench_emulation_run:
    """Real independent drops and the adaptive design of one configuration (feeder bench-emulation run)."""
    input:
        code("bench-emulation"),
        part=lambda wildcards: "{}/{}.stl".format(config["parts"]["dir"], wildcards.key.split("__")[0]),
    output:
        f"{EMULATION_DIR}/{{key}}.npz",
    log:
        f"{LOGS}/bench_emulation/{{key}}.log",
    benchmark:
        f"{BENCHMARKS}/bench_emulation/{{key}}.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        settings=lambda wildcards: emulation_run_settings(config, wildcards.key),
    shell:
        "feeder bench-emulation run --key {wildcards.key} --settings '{params.settings}' --out {output} > {log} 2>&1"


rule bench_emulation:
    """JS(P_N, P_all) of emulated against real drops, and the two-sample tests (feeder bench-emulation table)."""
    input:
        code("bench-emulation"),
        runs=expand(f"{EMULATION_DIR}/{{key}}.npz", key=EMULATION_KEYS),
    output:
        rows=report(
            f"{RESULTS}/tables/label_emulation.csv", caption="../report/label_emulation.rst", category="Simulation"
        ),
        summary=report(
            f"{RESULTS}/tables/label_emulation_summary.csv",
            caption="../report/label_emulation_summary.rst",
            category="Simulation",
        ),
    log:
        f"{LOGS}/bench_emulation/table.log",
    benchmark:
        f"{BENCHMARKS}/bench_emulation/table.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        settings=settings_json("labels", "sim.min_ok_mass", "sim.emulation_bench"),
    shell:
        "feeder bench-emulation table --runs {input.runs} --settings '{params.settings}'"
        " --out-csv {output.rows} --out-summary {output.summary} > {log} 2>&1"


rule bench_predict:
    """How fast the reference model answers for a part (feeder bench-predict): features from the
    STL, one configuration, the whole fence grid. Not in `bench`: it needs the trained model. Build
    it as its own target once the model exists, so no other job shares the cores while it times."""
    input:
        code("bench-predict"),
        model=f"{REFERENCE_MODEL_DIR}/model.pt",
        parts=expand("{dir}/{part}.stl", dir=config["parts"]["dir"], part=PREDICT_BENCH_PARTS),
    output:
        raw=f"{RESULTS}/tables/predict_speed.csv",
        summary=f"{RESULTS}/tables/predict_speed_summary.csv",
    log:
        f"{LOGS}/bench_predict/bench_predict.log",
    conda:
        "../envs/feeder.yaml"
    params:
        settings=settings_json("fences"),
        model_dir=lambda wildcards, input: Path(input.model).parent,
    shell:
        "feeder bench-predict --model {params.model_dir} --parts {input.parts}"
        " --settings '{params.settings}' --out {output.raw} --summary {output.summary} > {log} 2>&1"
