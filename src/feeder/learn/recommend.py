"""Rank fence configurations for a part: ``feeder recommend``.

The design question behind the study: which fences make a part leave at the orientation a
station downstream wants? For one part, a trained model predicts the 360-bin PMF of every
fence configuration of the study's grid (``fences`` in the Snakemake config: every type
combination of ``fences.combos`` on the angle grids) or of a given list, in one batch, and ranks
them by the predicted probability that the final yaw lies within ``--tolerance`` of ``--target``
(:func:`window_probability`; modulo the part's rotational symmetry, since a part turned by
360/n looks the same).

    feeder recommend [--model results/models/m3/seed0] --part my.stl --target 0 --tolerance 10

Without ``--model`` the study answers (:mod:`feeder.learn.study`): its simulated labels for the
configurations it simulated with this part, the structured predictor from the part's labelled
configurations at the others (about a third of a second each), else the analytic push PMF; the
column ``answer`` says which (``simulated``, ``structured``, ``neighbour`` when the study folder has
no structured predictor, ``analytic``).
``--model models/m3`` ranks by the paper's Model 3 (``feeder export-model``).

Predictions are only as good as the model (its card says how it did on unseen parts).
``--verify K`` checks the top K: each is simulated with the adaptive design and the study's
settings (:func:`verify_settings`: ``sim.preset``, ``scene``, ``sim.base_seed``, ``sim.adaptive``,
the budget ``sim.drops``), labelled as the workflow labels it (:func:`feeder.labels.pmf.sim_label`,
part frame), and its simulated probability of the window is printed beside the predicted one,
with the share of drops that leave the fences at all (``ok_mass``; jams and falls are the rest).

A model with the push block (``model.inputs: paper+push`` or ``fence+push``) needs ``--part`` as an
STL: the analytic push block of every configuration is computed from its outline
(:func:`feeder.learn.predict.push_inputs`).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from feeder.errors import FeederError
from feeder.labels.metrics import FULL_TURN_DEG
from feeder.learn.simulated import status_counts, verify_part, verify_settings

DEFAULT_TOP = 10  # configurations printed
# --verify adds these; ``statuses``: the simulated drops by status ("ok 20, jammed 12")
# how far each kind of answer may be off (rank); the printed table leaves out those blank in every row shown
ERROR_COLUMNS = ("structured_w1_deg", "label_w1_upper_deg", "analytic_w1_deg")
VERIFY_COLUMNS = ("simulated_probability", "ok_mass", "statuses", "simulations", "sim_cpu_s")


def window_probability(pmf, target_deg: float, tolerance_deg: float, order: int = 1) -> np.ndarray:
    """Probability that the yaw lies within ``tolerance_deg`` of ``target_deg`` or of any of its
    turns by ``360 / order`` (a part with n-fold symmetry looks the same there), on the circle.

    ``pmf``: (..., bins) over bins ``[i, i + 1) · 360 / bins``; a bin counts in proportion to its
    overlap with the window(s), so the result is exact for a PMF uniform within bins. Overlapping
    windows (``2 · tolerance ≥ 360 / order``) cover the whole circle: probability 1.
    """
    p = np.asarray(pmf, dtype=np.float64)
    if not (math.isfinite(target_deg) and 0.0 <= target_deg < FULL_TURN_DEG):
        raise FeederError(f"target must be in [0, 360), got {target_deg!r}")
    if not (math.isfinite(tolerance_deg) and tolerance_deg > 0):
        raise FeederError(f"tolerance must be > 0 degrees, got {tolerance_deg!r}")
    if int(order) != order or order < 1:
        raise FeederError(f"symmetry order must be a positive integer, got {order!r}")
    bins = p.shape[-1]
    width = FULL_TURN_DEG / bins
    period = FULL_TURN_DEG / order
    if 2 * tolerance_deg >= period:
        return p.sum(axis=-1)
    lo = np.arange(bins) * width
    weight = np.zeros(bins)
    for k in range(int(order)):
        centre = target_deg + k * period
        for shift in (-FULL_TURN_DEG, 0.0, FULL_TURN_DEG):  # the window may straddle 0/360
            a, b = centre - tolerance_deg + shift, centre + tolerance_deg + shift
            weight += np.clip(np.minimum(lo + width, b) - np.maximum(lo, a), 0.0, None) / width
    return p @ np.clip(weight, 0.0, 1.0)


def grid_configurations(fences: dict) -> list[str]:
    """Every configuration id of the study's fence grid (``fences.combos`` on the angle grids)."""
    from feeder.labels.grid import combo_grid

    return [cid for combo in fences["combos"] for cid in combo_grid(fences, combo)]


def rank(
    model, part_raw, frame_deg, config_ids, target_deg, tolerance_deg, order, push_raw=None, analytic=None
) -> pd.DataFrame:
    """Every configuration's predicted probability of the target window, best first (ties in the
    given order); columns ``config_id, loc1, loc2, probability, mode_deg`` (the PMF's largest bin,
    part frame; NaN for a uniform PMF). ``push_raw``: the push block of every configuration, for a ``paper+push`` model;
    ``analytic``: their analytic PMFs, for a ``base: prior`` model. The analytic predictor
    (``--model analytic``, whose PMF is over the drops that do not jam) adds ``predicted_ok_mass``
    and ``probability_overall`` (probability × ok mass) and is ranked by the latter."""
    from feeder.labels import metrics as L
    from feeder.labels.dataset import feeder_vector
    from feeder.lane.fences import parse_config_id

    if not config_ids:
        raise FeederError("no fence configurations to rank")
    pairs = [parse_config_id(c) for c in config_ids]
    feeder_raw = np.stack([feeder_vector(f1, f2) for f1, f2 in pairs])
    pmf, _ = model.predict(np.repeat(part_raw[None, :], len(pairs), axis=0), feeder_raw, push_raw, analytic)
    if model.label_frame == "principal":
        if frame_deg is None:
            raise FeederError(
                "this model predicts in the parts' feature frame: give --part, or features with frame_deg"
            )
        pmf = L.shift_pmf(pmf, -float(frame_deg))
    width = FULL_TURN_DEG / pmf.shape[1]
    frame = pd.DataFrame(
        {
            "config_id": config_ids,
            "loc1": [f1.spec for f1, _ in pairs],
            "loc2": [f2.spec for _, f2 in pairs],
            "probability": window_probability(pmf, target_deg, tolerance_deg, order),
            "mode_deg": np.where(
                [L.is_uniform(row) for row in pmf], np.nan, (np.argmax(pmf, axis=1) + 0.5) * width
            ),  # a uniform PMF has no mode (blank in the CSV)
        }
    )
    key = "probability"
    if push_raw is not None and hasattr(model, "ok_mass"):  # the analytic PMF: over the ok drops only
        frame["predicted_ok_mass"] = model.ok_mass(push_raw)
        frame["probability_overall"] = frame["probability"] * frame["predicted_ok_mass"]
        key = "probability_overall"  # a configuration that always jams does not top the ranking
    if hasattr(model, "sources"):  # the study's predictor: where each answer comes from
        frame["answer"] = model.sources()
    if hasattr(model, "structured_error_deg") and "structured" in frame.get("answer", pd.Series(dtype=str)).values:
        # how far the structured predictor lay from the simulator on held-out rows as far from
        # their nearest label as each structured answer is (the card's table)
        frame["structured_w1_deg"] = model.structured_error_deg()
    if hasattr(model, "label_error_deg") and "simulated" in frame.get("answer", pd.Series(dtype=str)).values:
        # how far each of the study's own labels may lie from the simulator's exact label (its audit)
        frame["label_w1_upper_deg"] = model.label_error_deg()
    if hasattr(model, "analytic_error_deg"):
        # how far the analytic PMF lay from the study's labels in each analytic answer's kind of
        # scene; among equal probabilities, the answer of a kind it gets right more often ranks first
        frame["analytic_w1_deg"] = model.analytic_error_deg()
        return frame.sort_values(
            [key, "analytic_w1_deg"], ascending=[False, True], kind="stable", na_position="first"
        ).reset_index(drop=True)
    return frame.sort_values(key, ascending=False, kind="stable").reset_index(drop=True)


def verify(geom, config_ids, settings: dict, target_deg, tolerance_deg, order, log=None) -> pd.DataFrame:
    """Simulate each configuration of ``config_ids`` with the adaptive design and ``settings``
    (:func:`verify_settings`) and return, per configuration, the simulated probability of the
    window (its label in the part frame), the ok mass, the drops by status, the simulations run
    and their CPU seconds (columns ``config_id`` and :data:`VERIFY_COLUMNS`). A configuration whose
    drops all jam or fall off is an answer too: ok mass 0, no simulated probability (NaN), its
    statuses counted; the other configurations are verified as usual. ``log``: called with a line
    before and after each configuration (progress)."""
    from feeder.labels.pmf import sim_label
    from feeder.lane.fences import parse_config_id
    from feeder.sim.record import record_of
    from feeder.sim.simulate import simulate

    rows = []
    for k, cid in enumerate(config_ids, start=1):
        loc1, loc2 = parse_config_id(cid)
        if log is not None:
            log(f"verify {k}/{len(config_ids)} {cid}: simulating ({settings['budget']} drops at most)")
        result = simulate(
            geom,
            loc1,
            loc2,
            settings["budget"],
            settings["seed"],
            settings["scene"],
            settings["preset"],
            settings["preset_name"],
            yaw_sampling="adaptive",
            adaptive=settings["adaptive"],
        )
        rec = record_of(result)
        statuses = status_counts(rec.status)
        probability, ok_mass = math.nan, 0.0
        if rec.ok.any():  # else every drop failed: no label, ok mass 0
            label = sim_label(rec, settings["bins"], settings["sigma"])
            ok_mass = label.ok_mass
            if ok_mass > 0:
                probability = float(window_probability(label.pmf, target_deg, tolerance_deg, order))
        cpu = float(result["cpu_s"])
        rows.append(
            {
                "config_id": cid,
                "simulated_probability": probability,
                "ok_mass": ok_mass,
                "statuses": statuses,
                "simulations": int(rec.status.size),
                "sim_cpu_s": cpu,
            }
        )
        if log is not None:
            log(f"verify {k}/{len(config_ids)} {cid}: {rec.status.size} simulations ({statuses}), {cpu:.1f} s CPU")
    return pd.DataFrame(rows, columns=["config_id", *VERIFY_COLUMNS])


def main(argv: list[str]) -> int:
    from feeder.config import add_settings_options, study_settings
    from feeder.learn.export import add_model_option
    from feeder.learn.predict import (
        check_part_arg,
        check_push_source,
        choose_model,
        part_vector,
        push_inputs,
        reads_contour_only,
    )

    parser = argparse.ArgumentParser(prog="feeder recommend", description=__doc__.splitlines()[0])
    add_model_option(parser)
    parser.add_argument("--part", type=Path, help="part geometry (.stl or .xyz)")
    parser.add_argument("--features", type=Path, help="precomputed features JSON instead of --part")
    parser.add_argument("--target", type=float, required=True, help="wanted final yaw, degrees in [0, 360)")
    parser.add_argument("--tolerance", type=float, required=True, help="half-width of the window, degrees")
    parser.add_argument(
        "--symmetry",
        default="auto",
        help="rotational order of the part: auto (from --part's outline; 1 with --features) or N",
    )
    parser.add_argument("--configs", help="comma-separated configuration ids (default: the study's fence grid)")
    parser.add_argument("--top", type=int, default=DEFAULT_TOP, help="configurations printed")
    parser.add_argument(
        "--out", type=Path, help="CSV of every ranked configuration (-: stdout, and the printed table goes to stderr)"
    )
    parser.add_argument(
        "--verify",
        type=int,
        default=0,
        metavar="K",
        help="simulate the top K (adaptive design, the study's settings) and print simulated beside predicted",
    )
    add_settings_options(parser)
    args = parser.parse_args(argv)

    window_probability(np.ones(1), args.target, args.tolerance)  # bad target/tolerance fail before any work
    check_window(args.tolerance, 1)  # a window of every yaw for any symmetry (and again below for the part's)
    if args.top < 1:
        raise FeederError(f"--top must be positive, got {args.top}")
    if args.verify < 0:
        raise FeederError(f"--verify must be 0 or more, got {args.verify}")
    needed = ("scene", "labels") + (() if args.configs else ("fences",)) + (("sim",) if args.verify else ())
    study = study_settings(args, *needed)
    model = choose_model(args.model, "feeder recommend", study)
    check_part_arg(args.part, args.features)
    geom = None
    if args.verify:
        geom = verify_part(args.part)
    if args.configs:
        config_ids = [c.strip() for c in args.configs.split(",") if c.strip()]
    else:
        config_ids = grid_configurations(study["fences"])
    settings = verify_settings(study) if args.verify else None
    order = symmetry_order(args.symmetry, args.part)
    check_window(args.tolerance, order)
    check_push_source(model, args.part)
    part_raw, frame_deg = part_vector(
        args.part, args.features, "feeder recommend", study.get("scene"), reads_contour_only(model)
    )
    if hasattr(model, "bind"):  # the study's predictor: which configurations it has simulated for this part
        print(f"feeder recommend: {model.bind(args.part, config_ids)}", file=sys.stderr)
        model.progress = lambda message: print(f"feeder recommend: {message}", file=sys.stderr, flush=True)
    push_raw = analytic = None
    if model.needs_push or model.needs_analytic:
        from feeder.lane.fences import parse_config_id

        pairs = [parse_config_id(c) for c in config_ids]
        push_raw, analytic = push_inputs(model, args.part, pairs, frame_deg, study)
    ranked = rank(model, part_raw, frame_deg, config_ids, args.target, args.tolerance, order, push_raw, analytic)
    shown = args.top
    if args.verify:
        top = list(ranked.config_id[: args.verify])

        def log(line: str) -> None:
            print(f"feeder recommend: {line}", file=sys.stderr)

        checked = verify(geom, top, settings, args.target, args.tolerance, order, log)
        ranked = ranked.merge(checked, on="config_id", how="left", validate="one_to_one")
        shown = max(args.top, len(top))
    to_stdout = args.out is not None and str(args.out) == "-"
    if to_stdout:
        sys.stdout.write(ranked.to_csv(index=False, lineterminator="\n"))
    elif args.out is not None:
        from feeder.io import write_csv

        write_csv(args.out, ranked)
    human = sys.stderr if to_stdout else sys.stdout  # the table a person reads, off the CSV's stream
    sym = f", {order}-fold symmetric" if order > 1 else ""
    print(
        f"P(final yaw within {args.tolerance:g} deg of {args.target:g} deg{sym}), {len(ranked)} "
        f"configuration{'' if len(ranked) == 1 else 's'}:",
        file=human,
    )
    table = ranked.head(shown).rename(columns={"probability": "predicted", "simulated_probability": "simulated"})
    table = table.drop(columns=[c for c in ERROR_COLUMNS if c in table and table[c].isna().all()])  # none shown
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}", na_rep="-"), file=human)
    for note in (
        label_note(ranked.head(shown)),
        structured_note(ranked.head(shown)),
        analytic_note(ranked.head(shown)),
    ):
        if note:
            print(note, file=human)
    return 0


def label_note(shown: pd.DataFrame) -> str:
    """A line for the printed table when some of its answers are the study's own simulated labels:
    the largest of their audits' upper estimates of their error (column ``label_w1_upper_deg``),
    how many have none, and that these bounds are no means; '' otherwise."""
    if "label_w1_upper_deg" not in shown or "answer" not in shown:
        return ""
    mine = shown.label_w1_upper_deg[shown.answer == "simulated"]
    if mine.empty:
        return ""
    err = mine.dropna()
    labels = f"{mine.size} of these answers {'is' if mine.size == 1 else 'are'} the study's simulated label"
    labels += "" if mine.size == 1 else "s"
    if err.empty:
        return f"note: {labels}, without an audit estimate of their error; --verify K simulates the top K"
    without = f" ({mine.size - err.size} without one)" if mine.size > err.size else ""
    return (
        f"note: {labels}; their audits bound each one's circular W1 from the simulator's exact label, at most "
        f"{err.max():.1f} deg here{without} (upper bounds from a few audit drops, often loose, not comparable with "
        "the other columns' means; column label_w1_upper_deg); --verify K simulates the top K"
    )


def structured_note(shown: pd.DataFrame) -> str:
    """A line for the printed table when some of its answers are the structured predictor: how far
    it lay from the simulator on held-out rows as far from their nearest label (column
    ``structured_w1_deg``), '' otherwise."""
    if "structured_w1_deg" not in shown or "answer" not in shown:
        return ""
    mine = shown.structured_w1_deg[shown.answer == "structured"]
    err = mine.dropna()
    if err.empty:
        return ""
    spread = f"{err.min():.0f}" if round(err.min()) == round(err.max()) else f"{err.min():.0f}-{err.max():.0f}"
    unknown = f" ({mine.size - err.size} at a distance no held-out row had)" if mine.size > err.size else ""
    return (
        f"note: {mine.size} of these answers are the structured predictor, which lay {spread} deg{unknown} (mean "
        "circular W1, column structured_w1_deg) from the simulator on held-out rows as far from their nearest "
        "label; --verify K simulates the top K"
    )


def analytic_note(shown: pd.DataFrame) -> str:
    """A line for the printed table when some of its answers are the analytic PMF, whose
    probabilities read as certainties (1.000) where the push model has one basin: how far it lay
    from the study's labels in those kinds of scene (column ``analytic_w1_deg``), '' otherwise."""
    if "analytic_w1_deg" not in shown or "answer" not in shown:
        return ""
    err = shown.analytic_w1_deg[shown.answer == "analytic"].dropna()
    if err.empty:
        return ""
    spread = f"{err.min():.0f}" if err.min() == err.max() else f"{err.min():.0f}-{err.max():.0f}"
    return (
        f"note: {err.size} of these answers are the analytic push PMF, which lay {spread} deg (mean circular W1, "
        "column analytic_w1_deg) from the study's simulated labels in those kinds of scene: its probabilities "
        "are not certainties; --verify K simulates the top K"
    )


def symmetry_order(setting: str, part: Path | None) -> int:
    """The part's rotational order for ``--symmetry``: the given number, checked against the STL
    outline where there is one (:func:`feeder.parts.symmetry.check_order`, as ``feeder simulate``
    checks it), or for ``auto`` the order of its STL outline
    (:func:`feeder.parts.symmetry.rotational_order`; 1 without an STL)."""
    order = None
    if setting != "auto":
        try:
            order = int(setting)
        except ValueError:
            raise FeederError(f"--symmetry must be auto or a positive integer, got {setting!r}") from None
        if order < 1:
            raise FeederError(f"--symmetry must be auto or a positive integer, got {setting!r}")
    if part is None or part.suffix.lower() != ".stl" or not part.is_file():
        if order is None:
            print("feeder recommend: no STL to read the symmetry from: order 1", file=sys.stderr)
        return 1 if order is None else order
    from feeder.parts.geometry import load_profile
    from feeder.parts.symmetry import DEFAULT_MAX_ORDER, DEFAULT_SYMMETRY_TOLERANCE, check_order, rotational_order

    outline, holes, _ = load_profile(part, "auto")
    if order is None:
        order = rotational_order(outline, holes=holes)
        if order == DEFAULT_MAX_ORDER:  # the most the check looks for: a round part stops there too
            print(
                f"feeder recommend: the part is {order}-fold symmetric or more ({order} is the most checked; a part "
                f"round to {100 * DEFAULT_SYMMETRY_TOLERANCE:g} % of its radius stops there): scored as {order}-fold; "
                "--symmetry N checks another order",
                file=sys.stderr,
            )
        return order
    try:
        check_order(outline, order, holes=holes)
    except FeederError as err:
        raise FeederError(f"--symmetry {order}: {err}") from None
    return order


def check_window(tolerance_deg: float, order: int) -> None:
    """A one-line FeederError for a window that covers the whole circle: ``±tolerance_deg`` about
    each of the target's ``order`` turns (:func:`window_probability`), where every configuration
    would score 1 and the ranking would say nothing."""
    period = FULL_TURN_DEG / order
    if 2 * tolerance_deg >= period:
        sym = f" and its turns by {period:g} deg ({order}-fold symmetric)" if order > 1 else ""
        raise FeederError(
            f"--tolerance {tolerance_deg:g} deg: the window about the target{sym} covers every yaw, so every "
            f"configuration would score 1; give less than {period / 2:g} deg"
        )
