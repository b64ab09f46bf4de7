# Regression models of paper Table 2 (Hydra configs in config/hydra/model/), Tables 5-8 with baselines
# and breakdowns, the leave-parts-out GroupKFold table and Figs. 12-13 (one job writes their data
# to results/figdata/, one drawing job per figure). Uses DATASET (datasets.smk), code (common.smk).
#
# Each model's resolved Hydra config is a param of its training job, so editing one
# config/hydra/model/mK.yaml reruns only model K (and the tables that read it).
# Every model is trained once per seed of models.seeds (results/models/{model}/seed{seed}/); the
# tables average over seeds and give the spread across them, and model_vs_baselines.csv holds the
# paired bootstrap of each model against each baseline (models.bootstrap).
# The §3.4.1 grid search is not part of the DAG: `feeder train -m hparams_search=grid model=m3`.
import os
import shlex

from feeder.config import resolved_yaml
from feeder.learn.export import shipped_models
from feeder.learn.train import resolved_config_yaml

MODELS = config["models"]["regression"]
HYDRA_OVERRIDES = config["models"]["hydra_overrides"]
HYDRA_ARGS = " ".join(shlex.quote(o) for o in HYDRA_OVERRIDES)
REFERENCE_MODEL = "m3"  # the paper's Model 3: Figs. 12-13 and the GroupKFold table
SEEDS = config["models"]["seeds"]
# the models whose leave-parts-out GroupKFold is run: Model 3 always (the export's card reads it)
GROUPKFOLD = list(dict.fromkeys([REFERENCE_MODEL, *config["models"]["groupkfold"]]))
# the first seed's Model 3: Figs. 12-13 and the model `feeder predict` uses
REFERENCE_MODEL_DIR = f"{RESULTS}/models/{REFERENCE_MODEL}/seed{SEEDS[0]}"
EXPORT_DIR = config["models"]["export_dir"]  # the shipped models' folder (models/ in the default study)
SHIPPED = shipped_models(config["models"])  # Model 3, then models.ship beside it
BOOTSTRAP_ARGS = "--resamples {resamples} --level {level} --bootstrap-seed {seed}".format(
    **config["models"]["bootstrap"]
)

MODELS_TARGETS = [
    *expand(f"{RESULTS}/tables/table{{n}}.{{ext}}", n=[5, 6, 7, 8], ext=["csv", "md"]),
    f"{RESULTS}/tables/model_vs_baselines.csv",
    *expand(f"{RESULTS}/tables/groupkfold_{{model}}{{suffix}}.csv", model=GROUPKFOLD, suffix=["", "_paired"]),
    *expand(f"{RESULTS}/tables/breakdown_{{split}}.{{ext}}", split=["fences", "parts"], ext=["csv", "md"]),
    f"{RESULTS}/tables/generalisation.csv",
    f"{RESULTS}/tables/generalisation_by_set.csv",
    f"{RESULTS}/tables/neighbour.csv",
    f"{RESULTS}/figures/fig12_test_predictions.png",
    f"{RESULTS}/figures/fig13_parts_predictions.png",
    *expand(f"{EXPORT_DIR}/{{model}}", model=SHIPPED),
    f"{EXPORT_DIR}/study",
]
# resolved Hydra settings of every model the DAG can train (composed once, at parse time)
HYDRA_SETTINGS = {
    m: resolved_config_yaml(m, HYDRA_OVERRIDES) for m in dict.fromkeys([*MODELS, REFERENCE_MODEL, *GROUPKFOLD])
}


rule train_model:
    """Train one regression model (Hydra config config/hydra/model/{model}.yaml) on the train split,
    with one seed of models.seeds."""
    input:
        code("train"),
        dataset=DATASET,
    output:
        model=f"{RESULTS}/models/{{model}}/seed{{seed}}/model.pt",
        metrics=f"{RESULTS}/models/{{model}}/seed{{seed}}/metrics.json",
    log:
        f"{LOGS}/models/train_{{model}}_seed{{seed}}.log",
    benchmark:
        f"{BENCHMARKS}/models/train_{{model}}_seed{{seed}}.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        hydra=lambda w: HYDRA_SETTINGS[w.model],
        overrides=HYDRA_ARGS,
    shell:
        "feeder train model={wildcards.model} seed={wildcards.seed} paths.dataset={input.dataset}"
        " paths.out=$(dirname {output.model}) hydra.run.dir=$(dirname {output.model})/hydra"
        " {params.overrides} > {log} 2>&1"


rule evaluate_models:
    """Tables 5-8 (Train, Test, Fences, Parts) with the baselines, the Fences/Parts breakdowns and
    every model against each baseline (paired bootstrap over configurations)."""
    input:
        code("evaluate"),
        dataset=DATASET,
        models=expand(f"{RESULTS}/models/{{model}}/seed{{seed}}/model.pt", model=MODELS, seed=SEEDS),
    output:
        t5=report(f"{RESULTS}/tables/table5.csv", caption="../report/table5.rst", category="Models"),
        t6=report(f"{RESULTS}/tables/table6.csv", caption="../report/table6.rst", category="Models"),
        t7=report(f"{RESULTS}/tables/table7.csv", caption="../report/table7.rst", category="Models"),
        t8=report(f"{RESULTS}/tables/table8.csv", caption="../report/table8.rst", category="Models"),
        md=[
            report(f"{RESULTS}/tables/table{n}.md", caption=f"../report/table{n}.rst", category="Models")
            for n in (5, 6, 7, 8)
        ],
        breakdowns=[
            report(
                f"{RESULTS}/tables/breakdown_{split}.{ext}",
                caption=f"../report/breakdown_{split}.rst",
                category="Models",
            )
            for split in ("fences", "parts")
            for ext in ("csv", "md")
        ],
        paired=report(
            f"{RESULTS}/tables/model_vs_baselines.csv", caption="../report/model_vs_baselines.rst", category="Models"
        ),
        paired_md=f"{RESULTS}/tables/model_vs_baselines.md",
    log:
        f"{LOGS}/models/evaluate.log",
    benchmark:
        f"{BENCHMARKS}/models/evaluate.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        bootstrap=BOOTSTRAP_ARGS,
        hydra=HYDRA_SETTINGS[REFERENCE_MODEL],  # holds the prior node: the analytic prior's grids
        overrides=HYDRA_ARGS,
    shell:
        "feeder evaluate tables --dataset {input.dataset} --models $(dirname {input.models})"
        " --out-dir $(dirname {output.t5}) {params.bootstrap} {params.overrides} > {log} 2>&1"


rule groupkfold_model:
    """Leave-parts-out GroupKFold of one model: one training per fold of datasets.group_folds and
    seed of models.seeds, and the model against both baselines paired over parts."""
    input:
        code("evaluate"),
        dataset=DATASET,
    output:
        csv=report(f"{RESULTS}/tables/groupkfold_{{model}}.csv", caption="../report/groupkfold.rst", category="Models"),
        md=report(f"{RESULTS}/tables/groupkfold_{{model}}.md", caption="../report/groupkfold.rst", category="Models"),
        paired=report(
            f"{RESULTS}/tables/groupkfold_{{model}}_paired.csv",
            caption="../report/groupkfold_paired.rst",
            category="Models",
        ),
        paired_md=f"{RESULTS}/tables/groupkfold_{{model}}_paired.md",
    log:
        f"{LOGS}/models/groupkfold_{{model}}.log",
    benchmark:
        f"{BENCHMARKS}/models/groupkfold_{{model}}.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        hydra=lambda w: HYDRA_SETTINGS[w.model],
        overrides=HYDRA_ARGS,
        seeds=" ".join(str(s) for s in SEEDS),
        bootstrap=BOOTSTRAP_ARGS,
    shell:
        "feeder evaluate groupkfold --dataset {input.dataset} --out {output.csv} --paired-out {output.paired}"
        " --seeds {params.seeds} {params.bootstrap} model={wildcards.model} {params.overrides} > {log} 2>&1"


rule generalisation:
    """Every predictor on unseen parts side by side (models.groupkfold, the baselines, the analytic
    push PMF): GroupKFold and the Parts split, each against the mean PMF paired over parts."""
    input:
        code("evaluate"),
        groupkfold=expand(f"{RESULTS}/tables/groupkfold_{{model}}.csv", model=GROUPKFOLD),
        parts=f"{RESULTS}/tables/table8.csv",
    output:
        csv=report(f"{RESULTS}/tables/generalisation.csv", caption="../report/generalisation.rst", category="Models"),
        md=f"{RESULTS}/tables/generalisation.md",
    log:
        f"{LOGS}/models/generalisation.log",
    benchmark:
        f"{BENCHMARKS}/models/generalisation.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        bootstrap=BOOTSTRAP_ARGS,
    shell:
        "feeder evaluate generalisation --groupkfold {input.groupkfold} --parts-table {input.parts}"
        " --out {output.csv} {params.bootstrap} > {log} 2>&1"


rule generalisation_by_set:
    """The GroupKFold of every predictor by library set: all parts, the protocol parts, the wider
    library (datasets.wide), each against the mean PMF paired over the set's parts."""
    input:
        code("generalisation-sets"),
        groupkfold=expand(f"{RESULTS}/tables/groupkfold_{{model}}.csv", model=GROUPKFOLD),
        configurations=f"{RESULTS}/datasets/configurations.csv",
    output:
        csv=report(
            f"{RESULTS}/tables/generalisation_by_set.csv",
            caption="../report/generalisation_by_set.rst",
            category="Models",
        ),
        md=f"{RESULTS}/tables/generalisation_by_set.md",
    log:
        f"{LOGS}/models/generalisation_by_set.log",
    benchmark:
        f"{BENCHMARKS}/models/generalisation_by_set.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        bootstrap=BOOTSTRAP_ARGS,
    shell:
        "feeder generalisation-sets --groupkfold {input.groupkfold} --configurations {input.configurations}"
        " --out {output.csv} {params.bootstrap} > {log} 2>&1"


rule neighbour:
    """Known parts at new angles: each Test configuration from the part's nearest simulated angle
    (rolled by the analytic model's shift), against the analytic and mean PMFs on the repeated Main
    splits of the structured protocol (feeder neighbour; config/hydra/structured.yaml)."""
    input:
        code("neighbour"),
        dataset=DATASET,
    output:
        csv=report(f"{RESULTS}/tables/neighbour.csv", caption="../report/neighbour.rst", category="Models"),
        rows=f"{RESULTS}/neighbour/neighbour_rows.csv",  # every row kept: raw data, not a report table
    log:
        f"{LOGS}/models/neighbour.log",
    benchmark:
        f"{BENCHMARKS}/models/neighbour.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        settings=resolved_yaml(
            "structured",
            drop=("candidates", "calibration", "blend", "model", "train", "search", "analytic_scenes"),
        ),
    shell:
        "feeder neighbour --dataset {input.dataset} --out-csv {output.csv} --out-rows {output.rows} > {log} 2>&1"


STRUCTURED_OVERRIDES = config["structured"]["hydra_overrides"]
# the structured predictor's evidence, quoted by the study's card: the protocol's table of this results
# folder, committed for the default study (feeder structured, run by hand: about 40 minutes, not in the
# DAG); an input only where it is (checked when the workflow is read)
STRUCTURED_TABLE = f"{RESULTS}/tables/structured_protocol.csv"
STRUCTURED_ERRORS = f"{RESULTS}/tables/structured_by_distance.csv"  # written beside it by the same command


rule fit_structured:
    """The shipped structured predictor: the protocol's fit (validation parts, search, seeds) on every
    configuration of the study, as one file that models/study answers a known part at a new angle
    with (feeder fit-structured; feeder.learn.structured_shipped; config/hydra/structured.yaml). The
    candidates it computes are kept beside the dataset for `feeder structured`, and so are the
    calibration modes' PMFs (structured_calibration.npz, a keyed cache, not an output: it survives a
    rerun, and is recomputed only when its key changes; about 20 minutes on 2 cores)."""
    input:
        code("fit-structured"),
        dataset=DATASET,
        sims=[sim_path(p, c) for p, c in zip(CONFIGS["part"], CONFIGS["config_id"])],
        parts=expand("{dir}/{part}.stl", dir=config["parts"]["dir"], part=sorted(set(CONFIGS["part"]))),
        features=expand(f"{RESULTS}/features/{{part}}.json", part=sorted(set(CONFIGS["part"]))),
    output:
        model=f"{RESULTS}/models/structured/structured.npz",
        candidates=f"{RESULTS}/datasets/structured_candidates.npz",
    log:
        f"{LOGS}/models/fit_structured.log",
    benchmark:
        f"{BENCHMARKS}/models/fit_structured.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        settings=resolved_yaml("structured", STRUCTURED_OVERRIDES, drop=("analytic_scenes", "answer_errors")),
        # neighbour.gates_deg: the blend's gate
        overrides=" ".join(shlex.quote(o) for o in STRUCTURED_OVERRIDES),
    shell:
        "feeder fit-structured --dataset {input.dataset} --sim-dir $(dirname $(dirname {input.sims[0]}))"
        " --parts-dir $(dirname {input.parts[0]}) --features-dir $(dirname {input.features[0]})"
        " --cache {output.candidates} --out {output.model} {params.overrides} > {log} 2>&1"


rule export_study:
    """The study's answer (models/study, committed): every simulated configuration as raw drops and
    the neighbour gate, chosen on every labelled configuration. `feeder predict` and `feeder recommend`
    answer from it without --model (feeder export-study; feeder.learn.study)."""
    input:
        code("export-study"),
        configurations=f"{RESULTS}/datasets/configurations.csv",
        sims=[sim_path(p, c) for p, c in zip(CONFIGS["part"], CONFIGS["config_id"])],
        parts=expand("{dir}/{part}.stl", dir=config["parts"]["dir"], part=sorted(set(CONFIGS["part"]))),
        dataset=DATASET,
        neighbour=f"{RESULTS}/tables/neighbour.csv",
        structured=f"{RESULTS}/models/structured/structured.npz",
        structured_table=lambda wildcards: [STRUCTURED_TABLE] if os.path.isfile(STRUCTURED_TABLE) else [],
        structured_errors=lambda wildcards: [STRUCTURED_ERRORS] if os.path.isfile(STRUCTURED_ERRORS) else [],
        label_errors=[f"{RESULTS}/tables/label_error_estimate.csv"] if AUDIT else [],
    output:
        directory(f"{EXPORT_DIR}/study"),
    log:
        f"{LOGS}/models/export_study.log",
    benchmark:
        f"{BENCHMARKS}/models/export_study.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        settings=resolved_yaml(
            "structured",
            drop=(
                "seed",
                "seeds",
                "candidates",
                "calibration",
                "blend",
                "model",
                "train",
                "search",
                "protocol",
                "answer_errors",
            ),
        ),
        evidence=lambda wildcards, input: (
            f"--structured-table {input.structured_table}" if input.structured_table else ""
        ),
        errors=lambda wildcards, input: (
            f"--structured-errors {input.structured_errors}" if input.structured_errors else ""
        ),
        label_errors=lambda wildcards, input: f"--label-errors {input.label_errors}" if input.label_errors else "",
    shell:
        "feeder export-study --configurations {input.configurations} --sim-dir $(dirname $(dirname {input.sims[0]}))"
        " --parts-dir $(dirname {input.parts[0]}) --dataset {input.dataset} --neighbour-table {input.neighbour}"
        " --structured {input.structured} {params.evidence} {params.errors} {params.label_errors} --out {output}"
        " > {log} 2>&1"


rule prediction_figure_data:
    """Data of Figs. 12 (Test) and 13 (Parts): four representative CDF predictions of Model 3 each."""
    input:
        code("evaluate"),
        dataset=DATASET,
        model=f"{REFERENCE_MODEL_DIR}/model.pt",
    output:
        fig12=f"{RESULTS}/figdata/fig12_test_predictions.npz",
        fig13=f"{RESULTS}/figdata/fig13_parts_predictions.npz",
    log:
        f"{LOGS}/models/prediction_figure_data.log",
    benchmark:
        f"{BENCHMARKS}/models/prediction_figure_data.tsv"
    conda:
        "../envs/feeder.yaml"
    shell:
        "feeder evaluate figure-data --dataset {input.dataset} --model $(dirname {input.model})"
        " --fig12-data {output.fig12} --fig13-data {output.fig13} > {log} 2>&1"


rule export_model:
    """A shipped model (models/<model>/, committed): the first seed's model with its scaler and a
    model card (training data, metrics on Test / Fences / Parts and unseen parts, the features'
    version). `feeder predict --model models/m3` and `feeder recommend --model models/m3` use it."""
    input:
        code("export-model"),
        model=f"{RESULTS}/models/{{model}}/seed{SEEDS[0]}/model.pt",
        dataset=DATASET,
        tables=[
            *expand(f"{RESULTS}/tables/table{{n}}.csv", n=[6, 7, 8]),
            f"{RESULTS}/tables/groupkfold_{{model}}.csv",
            f"{RESULTS}/tables/model_vs_baselines.csv",
        ],
    output:
        directory(f"{EXPORT_DIR}/{{model}}"),
    log:
        f"{LOGS}/models/export_model_{{model}}.log",
    benchmark:
        f"{BENCHMARKS}/models/export_model_{{model}}.tsv"
    conda:
        "../envs/feeder.yaml"
    shell:
        "feeder export-model --model $(dirname {input.model}) --tables $(dirname {input.tables[0]})"
        " --dataset {input.dataset} --out {output} > {log} 2>&1"
