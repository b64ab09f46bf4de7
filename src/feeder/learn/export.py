"""``feeder export-model``: copy a trained model into the repository's shipped-model folder with its card.

Also where ``feeder predict`` / ``feeder recommend`` find that folder (:func:`shipped_model_dir`).

    feeder export-model --model results/models/m3/seed0 --tables results/tables \\
        --dataset results/datasets/dataset.npz --out models/m3 [--provenance results/provenance.json]

The folder ``--out`` receives the files :meth:`feeder.learn.models.TrainedModel.save` writes
(``model.pt``, ``scaler.json``; copied byte for byte and loaded back to check them) and the model
card twice, ``card.json`` for programs and ``MODEL_CARD.md`` for people (:func:`build_card`):

* the model (name, seed, architecture, label frame, training run from its ``metrics.json``);
* ``features_version`` (:func:`feeder.labels.dataset.features_version`): the version of the 53
  inputs the code computed when the model was exported. ``feeder predict`` refuses a model whose
  card records another (:func:`check_card`): its inputs would mean something else;
* the training data, read from ``--dataset``: rows per split, parts, fence configurations, bins,
  label frame, and the simulation design (``sim.preset``, ``sim.yaw_sampling``, ``sim.drops``)
  from the dataset's settings or else from the ``--provenance`` config;
* the metrics of the model and both baselines (:data:`feeder.learn.evaluate.BASELINE_MEAN`,
  :data:`~feeder.learn.evaluate.BASELINE_NEAREST`) as ``feeder evaluate`` wrote them in ``--tables``:
  the rows of ``table6.csv`` (Test), ``table7.csv`` (Fences) and ``table8.csv`` (Parts), every
  column; the ``over parts`` rows of ``groupkfold_<model>.csv`` (unseen parts, when present) and
  the model's rows of ``model_vs_baselines.csv`` (when present).

The folder is written atomically: everything is built in a temporary sibling directory, which then
takes the place of ``--out`` (:func:`replace_dir`), so a crash leaves the previous folder or the new
one, never a half-written one. An existing ``--out`` is replaced only if it is an earlier export
(it holds ``card.json``) or empty.

Without ``--model``, ``feeder predict`` and ``feeder recommend`` use the shipped folder
:func:`shipped_model_dir` (``models/m3`` at the repository root; the environment variable
``FEEDER_MODEL_DIR`` points elsewhere).
"""

from __future__ import annotations

import argparse
import errno
import hashlib
import json
import math
import os
import shutil
import sys
import tempfile
from pathlib import Path

from feeder.errors import FeederError

CARD_FILE = "card.json"
CARD_MARKDOWN = "MODEL_CARD.md"
CARD_FORMAT = 1  # version of the layout of card.json
SHIPPED_ROOT = "models"  # the shipped-model folder's parent, at the repository root
SHIPPED_MODEL = "m3"  # the model feeder predict / recommend use by default
MODEL_DIR_ENV = "FEEDER_MODEL_DIR"  # overrides the shipped-model folder (tests, other checkouts)
# evaluate's split tables the card copies (split -> table number: evaluate.TABLES)
CARD_SPLITS = ("test", "fences", "parts")
OVER_PARTS = "over parts"  # the GroupKFold row over the per-part means (evaluate.groupkfold)
MODEL_VS_BASELINES = "model_vs_baselines.csv"
SIM_DESIGN_KEYS = ("preset", "yaw_sampling", "drops")  # of the config's sim section
TRAINING_KEYS = ("train_s", "best_epoch", "epochs_run", "best_val_loss", "n_fit", "n_val")  # of metrics.json
# renameat2(2) on Linux: swap two paths atomically (linux/fcntl.h, linux/fs.h)
_AT_FDCWD = -100
_RENAME_EXCHANGE = 2
_NO_EXCHANGE = (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP)  # the file system cannot swap


# ----------------------------------------------------------------------------------------------
# The shipped model
# ----------------------------------------------------------------------------------------------
def shipped_model_dir() -> Path:
    """The folder ``feeder predict`` / ``feeder recommend`` use without ``--model``: ``$FEEDER_MODEL_DIR``
    when set, else ``models/m3`` at the repository root (located from the package)."""
    override = os.environ.get(MODEL_DIR_ENV)
    if override:
        return Path(override)
    import feeder

    return Path(feeder.__file__).resolve().parents[2] / SHIPPED_ROOT / SHIPPED_MODEL


def shipped_models(models: dict) -> list[str]:
    """The models the workflow exports (the ``models`` section of the Snakemake config): Model 3,
    then ``models.ship``. Each of these needs its table rows and its GroupKFold, so one missing
    from ``models.regression`` or ``models.groupkfold`` is a one-line FeederError."""
    shipped = list(dict.fromkeys([SHIPPED_MODEL, *models["ship"]]))
    missing = [m for m in shipped[1:] if m not in models["regression"] or m not in models["groupkfold"]]
    if missing:
        raise FeederError(f"models.ship: {', '.join(missing)} must also be in models.regression and models.groupkfold")
    return shipped


def add_model_option(parser: argparse.ArgumentParser) -> None:
    """The ``--model`` option of ``feeder predict`` and ``feeder recommend`` (optional)."""
    parser.add_argument(
        "--model",
        type=Path,
        help="`study` (the default): the study's simulated label of a part and configuration it simulated; "
        "for a part it simulated, at another configuration, the structured predictor from that part's labels "
        "(else the label of its nearest simulated angle within the gate); else the analytic push PMF "
        "(models/study, written by `feeder export-study`; needs --part as an STL); `analytic`: the untrained "
        "analytic push PMF alone, the best answer for a new part by circular W1 (docs/results.md); or a trained "
        f"model directory, e.g. {shipped_model_dir()} (the paper's Model 3, `feeder export-model`; "
        f"${MODEL_DIR_ENV}, when set, names the model folder used without --model)",
    )


def resolve_model_dir(model: Path | None, prog: str = "feeder") -> Path:
    """``model`` when given, else the shipped folder (:func:`shipped_model_dir`), which must hold
    an exported model: its weights and its card. The choice is said on stderr. A relative
    ``model`` that is not in the working directory is looked for in the project
    (:func:`feeder.config.project_path`: ``--model models/m3prior`` works from any folder)."""
    if model is not None:
        from feeder.config import project_path

        found = project_path(model)
        if found != Path(model):
            print(f"{prog}: the model {found}", file=sys.stderr)
        return found
    from feeder.learn.spec import WEIGHTS_FILE

    shipped = shipped_model_dir()
    if not (shipped / WEIGHTS_FILE).is_file():
        raise FeederError(
            f"no shipped model is present in {shipped}: run `make run` to train and export one, "
            "or pass --model DIR (a trained model directory)"
        )
    if not (shipped / CARD_FILE).is_file():
        raise FeederError(f"the shipped model {shipped} has no {CARD_FILE}: export it with `feeder export-model`")
    check_card(shipped)  # before the note: an error stays the only line
    print(f"{prog}: the shipped model {shipped}", file=sys.stderr)
    return shipped


def read_card(model_dir: Path) -> dict | None:
    """The ``card.json`` of a model folder, or None when it has none."""
    path = Path(model_dir) / CARD_FILE
    if not path.is_file():
        return None
    try:
        card = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise FeederError(f"model card {path} is not readable JSON ({err})".replace("\n", " ")) from None
    if not isinstance(card, dict):
        raise FeederError(f"model card {path} is not a JSON object")
    return card


def check_card(model_dir: Path) -> None:
    """Refuse a model folder whose card records other model inputs than this code computes
    (``features_version``). A folder without a card (a ``feeder train`` output) is not checked."""
    from feeder.labels.dataset import features_version

    card = read_card(model_dir)
    if card is None:
        return
    spec = card.get("spec") if isinstance(card.get("spec"), dict) else {}
    inputs = str(spec.get("inputs") or "paper")  # a paper model's spec leaves it out
    try:
        ours = features_version(inputs)
    except FeederError:
        raise FeederError(f"the model card in {model_dir} names unknown model inputs {inputs!r}") from None
    theirs = card.get("features_version")
    if theirs != ours:
        raise FeederError(
            f"the model in {model_dir} was exported for features version {theirs}, this code computes "
            f"{ours}: retrain and re-export it (`make run`), or pass --model DIR"
        )


# ----------------------------------------------------------------------------------------------
# The card's contents
# ----------------------------------------------------------------------------------------------
def _plain(value):
    """A table cell as a JSON value: numpy scalars as Python ones, NaN and empty cells as None."""
    import numpy as np

    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _records(frame) -> list[dict]:
    return [{k: _plain(v) for k, v in row.items()} for row in frame.to_dict(orient="records")]


def _read_table(path: Path, columns: tuple[str, ...]):
    """A table of ``feeder evaluate`` (pandas reads its floats back exactly), with ``columns`` required."""
    import pandas as pd

    try:
        frame = pd.read_csv(path)
    except (OSError, ValueError, pd.errors.ParserError) as err:
        raise FeederError(f"table {path} is not a readable CSV ({err})".replace("\n", " ")) from None
    missing = [c for c in columns if c not in frame.columns]
    if missing:
        raise FeederError(f"table {path} lacks the column(s) {', '.join(missing)}")
    frame["model"] = frame["model"].astype(str)
    return frame


def _rows_of(frame, path: Path, names: list[str]) -> list[dict]:
    """The one row of each model in ``names`` (in that order), every column."""
    rows = []
    for name in names:
        sel = frame[frame["model"] == name]
        if len(sel) != 1:
            how = "no row" if sel.empty else f"{len(sel)} rows"
            raise FeederError(f"table {path} has {how} for {name} (run `feeder evaluate` with this model)")
        rows += _records(sel)
    return rows


def table_metrics(tables: Path, name: str, split_rows: dict[str, int]) -> dict:
    """The card's metrics: per split the rows of the model and both baselines in evaluate's
    Tables 6-8, the GroupKFold ``over parts`` rows and the model's rows of the paired comparison
    (None when those optional tables are missing). A Test/Fences/Parts table evaluated on another
    number of rows than ``split_rows`` gives (another dataset) is refused."""
    from feeder.learn.evaluate import BASELINE_ANALYTIC, BASELINE_MEAN, BASELINE_NEAREST, TABLES

    tables = Path(tables)
    names = [name, BASELINE_MEAN, BASELINE_NEAREST]
    out: dict = {}
    for split in CARD_SPLITS:
        path = tables / f"table{TABLES[split][0]}.csv"
        if not path.is_file():
            raise FeederError(f"table {path} is missing (run `feeder evaluate tables` first)")
        frame = _read_table(path, ("model",))
        # the analytic PMF's row too, where the dataset has it: the untrained answer to beat
        rows = _rows_of(frame, path, names + [BASELINE_ANALYTIC] * bool((frame["model"] == BASELINE_ANALYTIC).any()))
        for row in rows:
            n = row.get("n")
            if n is not None and int(n) != split_rows.get(split, 0):
                raise FeederError(
                    f"table {path}: {row['model']} was evaluated on {int(n)} {split} rows, the dataset has "
                    f"{split_rows.get(split, 0)}: the tables and --dataset do not belong together"
                )
        out[split] = rows
    path = tables / f"groupkfold_{name}.csv"
    if path.is_file():
        frame = _read_table(path, ("model", "group"))
        over = frame[frame["group"] == OVER_PARTS]
        out["unseen_parts"] = _rows_of(
            over, path, names + [BASELINE_ANALYTIC] * bool((over["model"] == BASELINE_ANALYTIC).any())
        )
    else:
        out["unseen_parts"] = None
    path = tables / MODEL_VS_BASELINES
    if path.is_file():
        frame = _read_table(path, ("model",))
        rows = _records(frame[frame["model"] == name])
        if not rows:
            raise FeederError(f"table {path} has no row for {name} (run `feeder evaluate tables` with this model)")
        out["model_vs_baselines"] = rows
    else:
        out["model_vs_baselines"] = None
    return out


def _read_json(path: Path, missing: str) -> dict:
    """A JSON object from ``path``; one-line errors (``missing`` says what to do when it is absent)."""
    try:
        obj = json.loads(path.read_text())
    except FileNotFoundError:
        raise FeederError(f"{path}: missing ({missing})") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise FeederError(f"{path}: not readable JSON ({err})".replace("\n", " ")) from None
    if not isinstance(obj, dict):
        raise FeederError(f"{path}: not a JSON object")
    return obj


def _read_provenance(path: Path | None) -> dict | None:
    return None if path is None else _read_json(Path(path), "the provenance file of the run")


def _sim_design(settings: dict | None) -> dict | None:
    """``sim.preset``, ``sim.yaw_sampling``, ``sim.drops`` of a config (None if it has none)."""
    sim = settings.get("sim") if isinstance(settings, dict) else None
    if not isinstance(sim, dict):
        return None
    picked = {k: sim[k] for k in SIM_DESIGN_KEYS if k in sim}
    return picked or None


def training_data(dataset: Path, provenance: dict | None) -> dict:
    """The card's description of the training data, from ``dataset.npz`` (and the provenance's
    config for the simulation design when the dataset does not record its settings)."""
    import numpy as np

    from feeder.labels.dataset import load_dataset
    from feeder.labels.grid import SPLITS

    data = load_dataset(dataset)
    split, parts = data["split"], data["part"]
    names = [s for s in SPLITS if s in set(split)] + sorted(set(split) - set(SPLITS))
    settings = None
    if "settings" in data:
        try:
            settings = json.loads(str(data["settings"]))
        except json.JSONDecodeError:
            raise FeederError(f"dataset file {dataset}: its settings are not JSON") from None
    sim, source = _sim_design(settings), "dataset"
    if sim is None and provenance is not None:
        sim, source = _sim_design(provenance.get("config")), "provenance"
    return {
        "dataset": str(dataset),
        "rows": int(split.size),
        "rows_per_split": {s: int((split == s).sum()) for s in names},
        "parts": int(np.unique(parts).size),
        "parts_per_split": {s: int(np.unique(parts[split == s]).size) for s in names},
        "configurations": int(np.unique(data["config_id"]).size),
        "bins": int(data["pmf"].shape[1]),
        "label_frame": str(data["label_frame"]) if "label_frame" in data else "part",
        "sim": sim,
        "sim_source": source if sim is not None else None,
    }


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def build_card(model_dir: Path, tables: Path, dataset: Path, provenance_path: Path | None = None) -> dict:
    """The contents of ``card.json`` for the trained model in ``model_dir`` (see the module doc)."""
    from feeder.labels.dataset import features_version, input_names
    from feeder.learn.models import SCALER_FILE, WEIGHTS_FILE, TrainedModel

    model_dir = Path(model_dir)
    model = TrainedModel.load(model_dir)
    metrics_path = model_dir / "metrics.json"
    metrics = _read_json(metrics_path, f"is {model_dir} a `feeder train` output?")
    name = model.spec.name
    provenance = _read_provenance(provenance_path)
    data = training_data(dataset, provenance)
    if data["label_frame"] != model.label_frame:
        raise FeederError(
            f"{model_dir} was trained on {model.label_frame}-frame labels, {dataset} holds {data['label_frame']}-frame "
            "ones: give the dataset the model was trained on"
        )
    return {
        "card_format": CARD_FORMAT,
        "model": name,
        "seed": metrics.get("seed"),
        "spec": model.spec.to_dict(),
        "label_frame": model.label_frame,
        "features_version": features_version(model.inputs),
        "inputs": list(input_names(model.inputs)),
        "training": {k: _plain(metrics[k]) for k in TRAINING_KEYS if k in metrics},
        "training_data": data,
        "metrics": table_metrics(tables, name, data["rows_per_split"]),
        "provenance": None
        if provenance is None
        else {k: provenance.get(k) for k in ("git_commit", "config_sha256") if k in provenance},
        "source": {
            "model": str(model_dir),
            "tables": str(tables),
            "dataset": str(dataset),
            "provenance": None if provenance_path is None else str(provenance_path),
        },
        "files": {f: _sha256(model_dir / f) for f in (WEIGHTS_FILE, SCALER_FILE)},
    }


# ----------------------------------------------------------------------------------------------
# MODEL_CARD.md
# ----------------------------------------------------------------------------------------------
def _table_md(rows: list[dict], caption: str) -> str:
    import pandas as pd

    from feeder.io import markdown_table

    frame = pd.DataFrame([{k: (math.nan if v is None else v) for k, v in row.items()} for row in rows])
    return markdown_table(frame, caption).rstrip("\n")


# what a model reads, by model.inputs (the card's "What it does")
CARD_INPUTS = {
    "paper": "the part's 45 DFT shape features and the 8 fence inputs (type and angle per location)",
    "paper+push": "the part's 45 DFT shape features, the 8 fence inputs (type and angle per location) and "
    "the analytic push features of the part's hull against each fence (from its STL)",
    "fence+push": "the 8 fence inputs (type and angle per location) and the analytic push features of the "
    "part's hull against each fence (from its STL), not the DFT shape features",
}


def card_markdown(card: dict) -> str:
    """``MODEL_CARD.md``: the card for a person (what it does, its training data, its metrics,
    its files)."""
    lines = _card_purpose(card) + _card_training(card) + _card_metrics(card) + _card_files(card)
    return "\n".join(lines) + "\n"


def _card_purpose(card: dict) -> list[str]:
    """The card's title, what the model does and how to call it."""
    name, spec = card["model"], card["spec"]
    seed = "unknown" if card["seed"] is None else card["seed"]
    inputs = str(spec.get("inputs") or "paper")  # a paper model's spec leaves it out
    model_option = f" --model {SHIPPED_ROOT}/{name}"  # without --model the study answers (feeder.learn.study)
    return [
        f"# Model card: {name} (seed {seed})",
        "",
        "Written by `feeder export-model`; the same in machine-readable form: `card.json`.",
        "",
        "## What it does",
        "",
        f"Predicts the {spec['bins']}-bin distribution (PMF and CDF) of the final yaw of a flat part that "
        f"rides a conveyor past two fence locations, from {CARD_INPUTS[inputs]}, without simulating. "
        f"Architecture: {spec['arch']} network, {spec['label']} labels ({spec['repr']}), "
        f"{spec['output_activation']} output"
        + (
            ", started from the analytic prior: its logits add log(λ · widened analytic PMF + (1 − λ) · "
            "training-mean PMF) of the configuration, (σ, λ) fitted on its training rows."
            if spec.get("base") == "prior"
            else "."
        ),
        "",
        "```",
        f"feeder predict{model_option} --part my.stl --loc1 straight:30 --loc2 none",
        f"feeder recommend{model_option} --part my.stl --target 0 --tolerance 10",
        "```",
        "",
        "Without `--model` both answer from the study's own simulations (`models/study`) and the analytic "
        "push PMF instead, which the tables support better. Predictions are only as good as the tables "
        "below: check an important configuration with `feeder simulate`.",
        "",
        f"- label frame: `{card['label_frame']}` (yaws of a `principal`-frame model are moved back to the "
        "part file's frame by `feeder predict`)",
        f"- features version: `{card['features_version']}` (`feeder predict` refuses this model when the "
        "code computes other features)",
        "",
    ]


def _card_training(card: dict) -> list[str]:
    """The card's training data: dataset, splits, simulation design and training run."""
    data = card["training_data"]
    lines = [
        "## Training data",
        "",
        f"- dataset: `{data['dataset']}`, {data['rows']} rows (part x fence configuration) of "
        f"{data['parts']} parts and {data['configurations']} fence configurations",
        "- rows (parts) per split: "
        + ", ".join(f"{s} {n} ({data['parts_per_split'][s]})" for s, n in data["rows_per_split"].items()),
    ]
    if data["sim"] is None:
        lines.append("- simulation design: not recorded (give --provenance)")
    else:
        design = ", ".join(f"sim.{k} = {v}" for k, v in data["sim"].items())
        lines.append(f"- simulation design (from the {data['sim_source']}): {design}")
    training = card["training"]
    if training:
        shown = (f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in training.items())
        lines.append("- training run: " + ", ".join(shown))
    return lines + [""]


def _card_metrics(card: dict) -> list[str]:
    """The card's metrics: the paper's split tables, unseen parts, and the paired comparison."""
    from feeder.learn.evaluate import TABLES

    seed = "unknown" if card["seed"] is None else card["seed"]
    lines = [
        "## Metrics",
        "",
        "From `feeder evaluate` (CDF R², W1 in degrees; mean ± SD over the configurations of a split). "
        "With several training seeds the model's columns are the mean over seeds (`seeds`, `*_seed_sd`); "
        f"the weights shipped here are seed {seed}.",
        "",
    ]
    metrics = card["metrics"]
    lines += [card_headline(card["model"], metrics), ""]
    for split in CARD_SPLITS:
        number, caption = TABLES[split]
        lines += [_table_md(metrics[split], f"Table {number}. {caption}"), ""]
    if metrics["unseen_parts"] is None:
        lines += ["Unseen parts (leave-parts-out GroupKFold): not evaluated.", ""]
    else:
        caption = "Unseen parts: leave-parts-out GroupKFold, mean ± SD of the per-part means (over parts)"
        lines += [_table_md(metrics["unseen_parts"], caption), ""]
    if metrics["model_vs_baselines"] is not None:
        caption = "Model against the baselines: paired differences (model − baseline) with bootstrap intervals"
        lines += [_table_md(metrics["model_vs_baselines"], caption), ""]
    return lines


def card_headline(name: str, metrics: dict) -> str:
    """The card's headline: the model's circular W1 (degrees, lower is better) on Test, Fences,
    Parts and unseen parts, each beside the analytic PMF's and the mean PMF's where the tables hold
    them (pure)."""
    from feeder.learn.evaluate import BASELINE_ANALYTIC, BASELINE_MEAN

    shown = {"test": "Test", "fences": "Fences", "parts": "Parts", "unseen_parts": "unseen parts (GroupKFold)"}
    parts = []
    for key, label in shown.items():
        rows = {r["model"]: r for r in metrics.get(key) or []}
        if name not in rows:
            continue
        others = [
            f"{what} {rows[b]['cw1_mean']:.1f}°"
            for b, what in ((BASELINE_ANALYTIC, "analytic PMF"), (BASELINE_MEAN, "mean PMF"))
            if b in rows
        ]
        parts.append(f"{label} {rows[name]['cw1_mean']:.1f}°" + (f" ({', '.join(others)})" if others else ""))
    return (
        "Headline, circular W1 in degrees (lower is better; the paper's R² is in the tables below and "
        "rewards a hedged answer): " + "; ".join(parts) + "."
    )


SPLIT_NAMES = {
    "test": "known parts at new angles (Test)",
    "fences": "new fence combinations (Fences)",
    "parts": "new parts (Parts)",
}


def worse_than_analytic(card: dict) -> str | None:
    """Where the card's paired comparisons (``metrics.model_vs_baselines``) find the model worse
    than the untrained analytic push PMF by circular W1, one sentence saying so with the means and
    the interval; None where they find it nowhere worse (or the card has no comparisons) (pure)."""
    from feeder.learn.evaluate import BASELINE_ANALYTIC

    name = (card.get("model") or {}).get("name") if isinstance(card.get("model"), dict) else card.get("model")
    rows = (card.get("metrics") or {}).get("model_vs_baselines") or []
    worse = [
        r
        for r in rows
        if r.get("baseline") == BASELINE_ANALYTIC
        and r.get("metric") == "cw1"
        and r.get("verdict") == "worse"
        and (name is None or r.get("model") == name)
    ]
    if not worse:
        return None
    said = "; ".join(
        f"{SPLIT_NAMES.get(r['split'], r['split'])} {r['model_mean']:.1f}° against {r['baseline_mean']:.1f}° "
        f"(+{r['diff_mean']:.1f}° [{r['diff_low']:.1f}, {r['diff_high']:.1f}], {100 * r['level']:.0f} % paired)"
        for r in worse
    )
    return (
        f"on the study's tables this model lies further from the simulator than the untrained analytic push PMF "
        f"(circular W1: {said}); --model study or --model analytic answers a new part with that PMF"
    )


def _card_files(card: dict) -> list[str]:
    """The card's files with their digests, and the provenance of the run."""
    lines = ["## Files", ""]
    lines += [f"- `{f}`: sha256 `{digest}`" for f, digest in card["files"].items()]
    provenance = card["provenance"]
    if provenance:
        lines.append("- provenance: " + ", ".join(f"{k} `{v}`" for k, v in provenance.items()))
    return lines


# ----------------------------------------------------------------------------------------------
# Writing the folder atomically
# ----------------------------------------------------------------------------------------------
def _exchange(a: Path, b: Path) -> bool:
    """Swap two existing paths in one step (Linux ``renameat2(RENAME_EXCHANGE)``); False where the
    system or the file system cannot."""
    if not sys.platform.startswith("linux"):
        return False
    import ctypes

    try:
        renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    if renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in _NO_EXCHANGE:
        return False
    raise OSError(err, os.strerror(err), str(b))


def replace_dir(new: Path, out: Path) -> None:
    """Put the finished folder ``new`` (a sibling of ``out``) at ``out``, replacing an existing one.

    A missing ``out`` is one rename. An existing one is swapped with ``new`` in one step where the
    system can (Linux), then deleted; elsewhere it is first moved aside, and moved back should the
    second rename fail."""
    if not out.exists():
        os.rename(new, out)
        return
    if _exchange(new, out):
        shutil.rmtree(new, ignore_errors=True)  # the old folder, now under the temporary name
        return
    aside = Path(tempfile.mkdtemp(prefix=f".{out.name}.old.", suffix=".tmp", dir=out.parent))
    os.rename(out, aside / out.name)
    try:
        os.rename(new, out)
    except OSError:
        os.rename(aside / out.name, out)  # should this fail too, the old folder stays in ``aside``
        os.rmdir(aside)
        raise
    shutil.rmtree(aside, ignore_errors=True)


def _check_out(out: Path) -> None:
    """Refuse to replace anything but an earlier export (or an empty folder)."""
    if not out.exists():
        return
    if not out.is_dir():
        raise FeederError(f"--out {out} is a file, not a model folder")
    if not (out / CARD_FILE).is_file() and any(out.iterdir()):
        raise FeederError(f"--out {out} exists and is not an exported model folder (no {CARD_FILE}): not replacing it")


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def export_model(model_dir, tables, dataset, out, provenance=None) -> dict:
    """Write the shipped-model folder ``out`` (model files, ``card.json``, ``MODEL_CARD.md``)
    atomically; returns the card."""
    from feeder.io import write_json, write_text
    from feeder.learn.models import SCALER_FILE, WEIGHTS_FILE, TrainedModel

    model_dir, out = Path(model_dir), Path(out)
    _check_out(out)
    card = build_card(model_dir, Path(tables), Path(dataset), None if provenance is None else Path(provenance))

    def fill(work: Path) -> None:
        for name in (WEIGHTS_FILE, SCALER_FILE):
            shutil.copyfile(model_dir / name, work / name)
        TrainedModel.load(work)  # the copies load
        write_json(work / CARD_FILE, card)
        write_text(work / CARD_MARKDOWN, card_markdown(card))

    write_folder(out, fill)
    return card


def write_folder(out: Path, fill) -> None:
    """``out`` all or nothing: ``fill(work)`` writes a sibling temporary folder, which then replaces
    ``out`` (:func:`replace_dir`); the temporary folder never outlives a failure."""
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        work = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent))
    except OSError as err:
        raise FeederError(f"cannot write {out} ({err.strerror})") from None
    try:
        fill(work)
        os.chmod(work, 0o777 & ~_umask())  # mkdtemp's folder is private; a result gets the usual mode
        try:
            replace_dir(work, out)
        except OSError as err:
            raise FeederError(f"cannot write {out} ({err.strerror})") from None
    finally:
        if work.exists():
            shutil.rmtree(work, ignore_errors=True)


# ----------------------------------------------------------------------------------------------
# CLI
# ----------------------------------------------------------------------------------------------
def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder export-model", description=__doc__.split("\n")[0])
    parser.add_argument("--model", type=Path, required=True, help="trained model directory (a `feeder train` output)")
    parser.add_argument("--tables", type=Path, required=True, help="the `feeder evaluate tables` directory")
    parser.add_argument("--dataset", type=Path, required=True, help="the dataset.npz the model was trained on")
    parser.add_argument("--out", type=Path, required=True, help="the shipped-model folder, e.g. models/m3 (replaced)")
    parser.add_argument("--provenance", type=Path, help="provenance JSON (git commit, config) of the run")
    args = parser.parse_args(argv)
    card = export_model(args.model, args.tables, args.dataset, args.out, args.provenance)
    print(f"feeder export-model: {card['model']} (seed {card['seed']}) -> {args.out}", file=sys.stderr)
    return 0
