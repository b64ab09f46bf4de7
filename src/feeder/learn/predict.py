"""``feeder predict``: the orientation PMF of one part behind one fence configuration, from what the
study knows of it (or a model you name), in about a second; ``--simulate BUDGET`` asks the simulator.

    feeder predict [--model results/models/m3/seed0] --part parts/<id>.stl --loc1 straight:30 --loc2 none \\
        [--out pmf.csv] [--plot pmf.png]

Without ``--model`` (or with ``--model study``) the study answers (:mod:`feeder.learn.study`, the
folder ``models/study``): the simulated label of a part and configuration it simulated; for a part it
simulated at a new configuration, the structured predictor from the part's labelled configurations
(:mod:`feeder.learn.structured_shipped`, about a second); else the untrained analytic push PMF; it
needs ``--part`` as an STL and says on stderr which answer it gave. ``--model analytic`` is the analytic
PMF alone; ``--model models/m3`` the paper's Model 3 (written by ``feeder export-model``). A model
folder with a card (``card.json``) whose features version is not the code's is refused
(:func:`feeder.learn.export.check_card`).

The part's 45 DFT features come from its ``.stl``/``.xyz`` (:func:`feeder.parts.features.features_of_file`)
or from a precomputed ``--features results/features/<id>.json``; the fences are parsed by
:func:`feeder.lane.fences.parse_location`. The output CSV has one row per bin: ``angle_deg`` (the
bin's lower edge in degrees), ``pmf`` (probability of the bin) and ``cdf`` (cumulative from 0°),
post-processed exactly as in evaluation, for the yaw of the part file's own frame (a model trained
on ``principal``-frame labels is shifted back by the part's ``frame_deg``). Without ``--out`` the
CSV goes to stdout. The time spent on features, push features and the answer itself is printed
to stderr in milliseconds.

A model with ``model.inputs: paper+push`` also reads the analytic push block of the part in the
configuration (:func:`push_inputs`: :func:`feeder.mechanics.features.push_features` of the STL's outline, in
the study config's scene and the model's label frame, as ``feeder datasets build`` computes it):
it needs ``--part`` as an STL (``--features`` and ``.xyz`` files hold no outline). So does a model
that starts from the analytic prior (``model.base: prior``): it reads the configuration's analytic
PMF, from the same pass (:func:`push_inputs`, :func:`feeder.mechanics.features.push_block`), smoothed as
the study config's labels are (``labels.sigma_bins``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from feeder.errors import FeederError

TOP_ORIENTATIONS = 3  # resting orientations feeder predict prints


def load_model(path: Path):
    """The model in ``path`` as :class:`feeder.learn.inference.NumpyModel`: its network answered in
    numpy, so that predict and recommend never import torch; an exported model only if its card's
    features version is the code's."""
    from feeder.learn import inference
    from feeder.learn.export import check_card

    check_card(path)
    return inference.load(path)


def say_standing(model_dir: Path, prog: str) -> None:
    """A note on stderr where the model's card finds it worse than the analytic push PMF
    (:func:`feeder.learn.export.worse_than_analytic`)."""
    from feeder.learn.export import read_card, worse_than_analytic

    card = read_card(model_dir)
    note = worse_than_analytic(card) if card is not None else None
    if note:
        print(f"{prog}: note: {model_dir}: {note}", file=sys.stderr)


def choose_model(model_arg, prog: str, study: dict):
    """The predictor ``--model`` names: the untrained analytic push PMF for ``analytic``
    (:class:`feeder.learn.analytic.AnalyticModel`, over the study's ``labels.bins``), else the
    trained model folder (:func:`load_model`; the shipped one without ``--model``). The choice is
    said on stderr."""
    from feeder.learn.analytic import AnalyticModel, is_analytic
    from feeder.learn.study import is_study, study_model

    if is_study(model_arg):
        model = study_model(study)
        known = "the structured predictor" if model.structured is not None else "its nearest simulated angle"
        print(
            f"{prog}: the study's answer (its simulated labels where it has the part and configuration, {known} "
            "where it has the part, else the analytic push PMF; --model study)",
            file=sys.stderr,
        )
        return model
    if is_analytic(model_arg):
        print(f"{prog}: the analytic push PMF (untrained; --model analytic)", file=sys.stderr)
        return AnalyticModel(int(study["labels"]["bins"]))
    from feeder.learn.export import resolve_model_dir

    model_dir = resolve_model_dir(model_arg, prog)
    model = load_model(model_dir)
    say_standing(model_dir, prog)
    return model


def check_part_fits(
    part: Path, prog: str = "feeder predict", scene: dict | None = None, contour_only: bool = True
) -> None:
    """Refuse an STL part the simulator refuses (wider than the belt, or too thin for the fences:
    :func:`feeder.sim.body.check_fit`, units as ``--units auto``): the model has never seen such a
    part and would answer for a scene that cannot happen. A face point cloud (``.xyz``) has no
    thickness and is not checked. ``contour_only``: the answer reads the part's DFT shape features,
    which describe its outer contour only (as in the paper), so a part with through-holes gets a
    note on stderr that the model does not see how the holes move its centre of mass (the analytic
    push model, the study's labels and the simulator all do: :func:`reads_contour_only`).
    ``scene``: the study's scene section (default: the study config's,
    :func:`feeder.lane.settings.load_settings`)."""
    if part.suffix.lower() != ".stl":
        return
    from feeder.lane.settings import load_settings
    from feeder.parts.geometry import MAX_PART_SIZE_M, load_profile, profile_moments
    from feeder.sim.body import check_fit

    outline, holes, thickness = load_profile(part, "auto")
    _, centroid, _ = profile_moments(outline, holes)
    hint = f" ({prog} reads a part file in metres, or in millimetres where it is over {MAX_PART_SIZE_M:g} m across)"
    scene = load_settings()[0] if scene is None else scene
    check_fit(part.stem, outline, centroid, thickness, scene, hint)
    tip = tipping_ratio(outline, centroid, thickness, scene)
    if tip >= 1.0:
        print(
            f"{prog}: note: {part.name} is tall for its width ({1e3 * thickness:.3g} mm thick): a fence pushing it "
            f"across its narrowest side would tip it over ({tip:.2f} of the tipping moment at the belt's friction "
            "or more; every part of the study stays below 1); only feeder simulate models that",
            file=sys.stderr,
        )
    if holes and contour_only:
        print(
            f"{prog}: note: {part.name} has {len(holes)} through-hole(s); the model sees its outer "
            "contour only, so check the answer with feeder simulate",
            file=sys.stderr,
        )


def tipping_ratio(outline, centroid, thickness: float, scene: dict) -> float:
    """How close a fence's push comes to tipping the part over, quasi-statically: ``μ·h / d``, the
    moment of the belt's friction ``μ·m·g`` (part × belt friction: the push that slides the part)
    applied at the height ``h`` of the fence contact's centre (midway between the gap under the
    fence and the part's top, or the fence's top) over the moment ``m·g·d`` of its weight about
    the edge it would tip over, ``d`` the centroid's distance from the far support line of the
    narrowest push (least over the hull's edges, each pushed flat by a fence). At 1 or more the
    part tips over where a fence pushes it across that side; the simulator shows such drops as
    flipped, and no other answer models them. A 40 x 20 mm plate 5 mm thick: 0.8 · 2.75 / 10 = 0.22."""
    from feeder.mechanics.hull import REL_TOL, convex_hull

    rel = np.asarray(outline, np.float64) - np.asarray(centroid, np.float64)
    size = float(np.max(np.ptp(rel, axis=0)))
    hull = convex_hull(rel, REL_TOL * size)
    edge = np.roll(hull, -1, axis=0) - hull
    normal = np.column_stack([edge[:, 1], -edge[:, 0]]) / np.hypot(edge[:, 0], edge[:, 1])[:, None]  # outward (CCW)
    far = np.max(-(hull @ normal.T), axis=0)  # the far support line's distance, per pushed edge
    fences = scene["fences"]
    gap = float(fences["clearance"])
    height = 0.5 * (gap + min(float(thickness), gap + float(fences["height"])))
    mu = float(scene["part"]["friction"]) * float(scene["belt"]["friction"])
    return mu * height / float(np.min(far))


def reads_contour_only(model) -> bool:
    """Whether ``model`` answers from the part's DFT shape features alone (a trained network,
    :class:`feeder.learn.inference.NumpyModel`, with the paper's inputs), which see its outer
    contour only. The analytic push PMF, the push block of a network's ``paper+push`` or
    ``fence+push`` inputs and the study's answers (labels, the structured predictor) see its holes."""
    from feeder.learn.inference import NumpyModel

    return isinstance(model, NumpyModel) and model.inputs == "paper"


def part_vector(
    part: Path | None,
    features: Path | None,
    prog: str = "feeder predict",
    scene: dict | None = None,
    contour_only: bool = True,
) -> tuple[np.ndarray, float | None]:
    """(the 45 raw DFT values, ``frame_deg`` or None) of a part, from its geometry file or a features
    JSON; ``prog`` names the command in a note on stderr; ``scene`` is the scene the part must fit
    and ``contour_only`` whether the answer sees the outer contour only (:func:`check_part_fits`)."""
    if (part is None) == (features is None):
        raise FeederError("give exactly one of --part or --features")
    if features is not None:
        from feeder.labels.dataset import load_features
        from feeder.parts.features import load_frame_deg

        try:
            frame = load_frame_deg(features)
        except FeederError:
            frame = None
        return load_features(features), frame
    if not part.is_file():
        raise FeederError(f"part file {part} is missing")
    check_part_fits(part, prog, scene, contour_only)
    from feeder.parts.features import as_vector, features_of_file

    feats = features_of_file(part)
    return as_vector(feats), feats["frame_deg"]


PART_SUFFIXES = (".stl", ".xyz")  # a part's solid, or its face as points (feeder parts xyz)


def check_part_arg(part: Path | None, features: Path | None) -> None:
    """A one-line FeederError, before any other work, for a part argument no answer can read:
    neither or both of ``--part`` and ``--features``, a missing path, a folder, or a file that is
    not an STL or a face point cloud."""
    if (part is None) == (features is None):
        raise FeederError("give exactly one of --part or --features")
    given, what = (part, "part file") if part is not None else (features, "features file")
    if given.is_dir():
        raise FeederError(f"{what} {given} is a folder, not a file")
    if not given.is_file():
        raise FeederError(f"{what} {given} not found")
    if part is not None and part.suffix.lower() not in PART_SUFFIXES:
        raise FeederError(f"{part}: unknown file type {part.suffix.lower()!r} (expected {' or '.join(PART_SUFFIXES)})")


def check_push_source(model, part: Path | None) -> None:
    """Refuse, before any work, a ``paper+push`` or ``base: prior`` model without a part outline
    to push: it needs ``--part`` as an STL. Models of the paper's inputs need nothing more."""
    if not (model.needs_push or model.needs_analytic):
        return
    if part is None or part.suffix.lower() != ".stl":
        what = (
            f"the analytic push features (model.inputs: {model.inputs})"
            if model.needs_push and hasattr(model, "scaler")
            else "the analytic PMF" + (" (model.base: prior)" if getattr(model.spec, "base", None) == "prior" else "")
        )
        raise FeederError(
            f"model {model.spec.name} takes {what}, computed from the part's outline: "
            "give --part PART.stl (a features JSON or .xyz file has no outline)"
        )


def push_inputs(
    model, part: Path | None, pairs, frame_deg: float | None, study: dict | None = None
) -> tuple[np.ndarray | None, ...]:
    """``(push block (N, P) or None, analytic PMFs (N, bins) or None)`` of the part for every
    (loc1, loc2) in ``pairs``, each only when ``model`` takes it. As the dataset has them: the
    STL's outline (units as ``--units auto``) in the study config's scene, in the model's label
    frame (``frame_deg`` of the part for a ``principal``-frame model, which it then needs) over
    the model's bins, the PMF smoothed as the study config's labels (``labels.sigma_bins``).
    ``study``: the study settings (``scene``, ``labels``; default: the study config of
    :func:`feeder.config.study_root`)."""
    if not (model.needs_push or model.needs_analytic):
        return None, None
    check_push_source(model, part)
    from feeder.config import load_study_config, study_root
    from feeder.labels.dataset import label_smooth_deg
    from feeder.mechanics.features import push_block
    from feeder.mechanics.fence import default_scene
    from feeder.mechanics.hull import push_geometry
    from feeder.parts.geometry import load_profile

    frame = 0.0
    if model.label_frame == "principal":
        if frame_deg is None:
            raise FeederError(
                "this model's push features are in the parts' feature frame and need the part's frame_deg, "
                f"which {part} does not give"
            )
        frame = float(frame_deg)
    outline, holes, _ = load_profile(part, "auto")
    geom = push_geometry(outline, holes)
    if study is None:
        study = load_study_config(root=study_root())
    scene, memo, bins = study.get("scene") or default_scene(), {}, int(model.spec.bins)
    smooth = label_smooth_deg(bins, float(study["labels"]["sigma_bins"]))
    rows = [
        push_block(geom, loc1, loc2, scene, frame_deg=frame, bins=bins, pmf_smooth_deg=smooth, responses=memo)
        for loc1, loc2 in pairs
    ]
    push = np.stack([r[0] for r in rows]) if model.needs_push else None
    analytic = np.stack([r[1] for r in rows]) if model.needs_analytic else None
    return push, analytic


def predict_frame(
    model,
    part_raw: np.ndarray,
    loc1: str,
    loc2: str,
    frame_deg: float | None = None,
    push_raw: np.ndarray | None = None,
    analytic: np.ndarray | None = None,
) -> pd.DataFrame:
    """The 360-bin prediction of ``model`` (a TrainedModel) as a DataFrame, in the part's own frame.

    A model trained on ``principal``-frame labels predicts the yaw of the part's feature frame;
    it is moved back by ``frame_deg`` (:func:`feeder.labels.metrics.shift_pmf`), which it then needs.
    ``push_raw``: the push block (:func:`push_inputs`) a ``paper+push`` model needs; ``analytic``:
    the analytic PMF (:func:`push_inputs`) a ``base: prior`` model needs.
    """
    from feeder.labels import metrics as L
    from feeder.labels.dataset import feeder_vector
    from feeder.lane.fences import parse_location

    feeder_raw = feeder_vector(parse_location(loc1), parse_location(loc2))
    push = None if push_raw is None else np.atleast_2d(push_raw)
    pmf, cdf = model.predict(part_raw[None, :], feeder_raw[None, :], push, analytic)
    if model.label_frame == "principal":
        if frame_deg is None:
            raise FeederError(
                "this model predicts in the parts' feature frame and needs the part's frame_deg: "
                "give --part, or a features JSON written by `feeder features`"
            )
        pmf = L.shift_pmf(pmf, -float(frame_deg))
        cdf = L.cdf(pmf)
    bins = pmf.shape[1]
    return pd.DataFrame({"angle_deg": np.arange(bins) * (360.0 / bins), "pmf": pmf[0], "cdf": cdf[0]})


def rotated_outline(outline, yaw_deg: float, centre=None) -> np.ndarray:
    """The outline (N, 2, metres, the part file's frame) turned by ``yaw_deg`` about ``centre``
    (default: the mean of its vertices), in millimetres: how the part lies on the belt at that
    final yaw. A hole is turned about its part's centre."""
    pts = np.asarray(outline, dtype=np.float64)
    pts = pts - (pts.mean(axis=0) if centre is None else np.asarray(centre, dtype=np.float64))
    a = np.radians(yaw_deg)
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    return 1e3 * pts @ rot.T


def draw_part(ax, outline, frame: pd.DataFrame, holes=()) -> None:
    """The part (and its through-holes) at its most likely final yaw, the belt running up the page (+y)."""
    from feeder.labels.metrics import is_uniform, resting_orientations

    pmf = frame["pmf"].to_numpy()
    uniform = is_uniform(pmf)
    yaw, mass = (0.0, 0.0) if uniform else resting_orientations(pmf, 1)[0]
    pts = rotated_outline(outline, yaw)
    closed = np.vstack([pts, pts[:1]])
    ax.fill(closed[:, 0], closed[:, 1], color="tab:blue", alpha=0.3)
    ax.plot(closed[:, 0], closed[:, 1], color="tab:blue", lw=1)
    centre = np.asarray(outline, dtype=np.float64).mean(axis=0)
    for hole in holes:
        cut = rotated_outline(hole, yaw, centre)
        cut = np.vstack([cut, cut[:1]])
        ax.fill(cut[:, 0], cut[:, 1], color="white")
        ax.plot(cut[:, 0], cut[:, 1], color="tab:blue", lw=1)
    r = float(np.max(np.abs(pts)))
    ax.annotate("", xy=(1.15 * r, 0.8 * r), xytext=(1.15 * r, -0.8 * r), arrowprops={"arrowstyle": "->"})
    ax.text(1.2 * r, 0, "belt", rotation=90, va="center", fontsize=8)
    ax.set_aspect("equal")
    ax.set_xlim(-1.3 * r, 1.45 * r)
    ax.set_ylim(-1.2 * r, 1.2 * r)
    ax.set_xlabel("mm")
    title = "no preferred yaw (uniform); as in the file" if uniform else f"most likely: {yaw:.1f} deg (p={mass:.2f})"
    ax.set_title(title, fontsize=9)


def plot(frame: pd.DataFrame, title: str, outline=None, holes=()):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if outline is None:
        fig, ax = plt.subplots(figsize=(6, 3))
    else:
        fig, (ax, part_ax) = plt.subplots(1, 2, figsize=(9, 3), gridspec_kw={"width_ratios": [2, 1]})
        draw_part(part_ax, outline, frame, holes)
    ax.bar(frame.angle_deg, frame.pmf, width=360.0 / len(frame), align="edge", color="tab:blue")
    ax.set_xlim(0, 360)
    ax.set_xlabel("final yaw [deg]")
    ax.set_ylabel("probability per bin")
    ax2 = ax.twinx()
    ax2.plot(frame.angle_deg, frame.cdf, color="black", lw=1)
    ax2.set_ylim(0, 1.02)
    ax2.set_ylabel("CDF")
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    return fig


def orientation_summary(frame, top: int = TOP_ORIENTATIONS) -> str:
    """The most likely resting orientations of a predicted PMF (part frame) with their
    probabilities (:func:`feeder.labels.metrics.resting_orientations`), one line; a uniform PMF
    (:func:`feeder.labels.metrics.is_uniform`) has none, and the line says so."""
    from feeder.labels.metrics import is_uniform, resting_orientations

    pmf = frame["pmf"].to_numpy()
    if is_uniform(pmf):
        return "no preferred final yaw: the answer is uniform, every orientation equally likely"
    modes = resting_orientations(pmf, top)
    return "most likely final yaws (part frame): " + ", ".join(f"{yaw:.1f} deg p={mass:.2f}" for yaw, mass in modes)


def _main_simulated(args) -> int:
    """``feeder predict --simulate BUDGET``: the simulator's answer, written like a model's."""
    from feeder.config import study_settings
    from feeder.learn.simulated import simulated_frame, verify_part

    if args.model is not None:
        raise FeederError("give --model or --simulate, not both")
    if args.simulate < 2:
        raise FeederError(f"--simulate: a budget of at least 2 drops (got {args.simulate})")
    if args.audit and args.audit < 2:
        raise FeederError(f"--audit: at least 2 audit drops, or 0 for none (got {args.audit})")
    if args.features is not None:
        raise FeederError("--simulate simulates the part: give it as --part PART.stl, not --features")
    check_part_arg(args.part, None)
    geom = verify_part(args.part)
    study = study_settings(args, "scene", "labels", "sim")
    check_part_fits(args.part, "feeder predict", study["scene"], contour_only=False)
    print(f"feeder predict: simulating at most {args.simulate} drops (the study's adaptive design)", file=sys.stderr)
    frame, info = simulated_frame(geom, args.loc1, args.loc2, args.simulate, study, audits=args.audit or 0)
    done = f"{info['simulations']} drops ({info['statuses']}), {info['cpu_s']:.1f} s CPU"
    if frame is None:  # every drop jammed, fell off or tipped over: no yaw to give (ok mass 0)
        raise FeederError(
            f"no orientation to give: none of the {info['simulations']} drops left the fences lying flat "
            f"({info['statuses']}; {info['cpu_s']:.1f} s CPU): ok mass 0"
        )
    if args.out is not None:
        from feeder.io import write_csv

        write_csv(args.out, frame)
    else:
        sys.stdout.write(frame.to_csv(index=False, lineterminator="\n"))
    summary = (
        orientation_summary(frame) + f"\nshare of drops that leave without jamming (simulated): {info['ok_mass']:.2f}"
    )
    print(summary, file=sys.stdout if args.out is not None else sys.stderr)
    if args.plot is not None:
        from feeder.io import save_figure
        from feeder.parts.geometry import load_profile

        outline, holes, _ = load_profile(args.part, "auto")
        title = f"simulated ({args.simulate} drops at most): {args.part.stem}, loc1 {args.loc1}, loc2 {args.loc2}"
        save_figure(args.plot, plot(frame, title, outline, holes))
    print(f"feeder predict: simulated {done}", file=sys.stderr)
    if "estimate" in info:
        est = info["estimate"]
        print(
            f"feeder predict: {est.audits} audit drops more ({info['audit_cpu_s']:.1f} s CPU, "
            f"{est.misses} contradicting the answer's map) put it within circular W1 {est.circular_w1_deg:.1f} deg "
            "and sup|dCDF| "
            f"{est.sup_cdf:.3f} of the simulator's exact answer (upper estimates, feeder audit)",
            file=sys.stderr,
        )
    return 0


def main(argv: list[str]) -> int:
    from feeder.config import add_settings_options, study_settings
    from feeder.learn.export import add_model_option

    parser = argparse.ArgumentParser(prog="feeder predict", description=__doc__.split("\n\n")[0])
    add_model_option(parser)
    parser.add_argument("--part", type=Path, help="part geometry (.stl or .xyz)")
    parser.add_argument("--features", type=Path, help="precomputed features JSON instead of --part")
    parser.add_argument("--loc1", required=True, help="none | straight:ANGLE | curved:ANGLE")
    parser.add_argument("--loc2", required=True, help="none | straight:ANGLE | curved:ANGLE")
    parser.add_argument(
        "--simulate",
        type=int,
        metavar="BUDGET",
        help="answer by simulating instead of a model: the study's adaptive design with at most BUDGET drops "
        "(>= 2; needs --part as an STL; seconds of CPU a drop; results/tables/frontier.csv: budget 8 is "
        "closer than every model)",
    )
    parser.add_argument(
        "--audit",
        type=int,
        metavar="K",
        help="with --simulate: K more drops at stratified random yaws (>= 2), which do not change the answer, "
        "and from them an upper estimate of its error (feeder audit; docs/performance.md)",
    )
    parser.add_argument("--out", type=Path, help="CSV path; - or unset: stdout")
    parser.add_argument("--plot", type=Path, help="also draw the PMF/CDF to this image")
    add_settings_options(parser)
    args = parser.parse_args(argv)
    if args.out is not None and str(args.out) == "-":  # the usual spelling of stdout, not a file named -
        args.out = None

    from feeder.lane.fences import parse_location

    parse_location(args.loc1), parse_location(args.loc2)  # bad fences fail before any work
    if args.plot is not None:
        from feeder.io import check_figure_path

        check_figure_path(args.plot)
    if args.simulate is not None:
        return _main_simulated(args)
    if args.audit is not None:
        raise FeederError("--audit estimates the error of a simulated answer: give it with --simulate")
    study = study_settings(args, "scene", "labels")
    model = choose_model(args.model, "feeder predict", study)
    check_part_arg(args.part, args.features)
    check_push_source(model, args.part)
    t0 = time.perf_counter()
    part_raw, frame_deg = part_vector(
        args.part, args.features, scene=study.get("scene"), contour_only=reads_contour_only(model)
    )
    if hasattr(model, "bind"):  # the study's predictor: what it knows of this part and configuration
        from feeder.lane.fences import config_id, parse_location

        known = model.bind(args.part, [config_id(parse_location(args.loc1), parse_location(args.loc2))])
        print(f"feeder predict: {known}; answer: {model.describe(0)}", file=sys.stderr)
    t_dft = time.perf_counter()
    push_raw, analytic = push_inputs(model, args.part, [(args.loc1, args.loc2)], frame_deg, study)
    t1 = time.perf_counter()
    frame = predict_frame(model, part_raw, args.loc1, args.loc2, frame_deg, push_raw, analytic)
    t2 = time.perf_counter()
    source = model.sources()[0] if hasattr(model, "sources") else "analytic"
    if source != "analytic" and not frame["pmf"].sum() > 0:
        raise FeederError(f"no orientation to give: in {model.describe(0)} no drop left the fences (ok mass 0)")
    if args.out is not None:
        from feeder.io import write_csv

        write_csv(args.out, frame)
    else:
        sys.stdout.write(frame.to_csv(index=False, lineterminator="\n"))
    # the summary a person reads: on stdout unless stdout carries the table
    summary = orientation_summary(frame)
    if hasattr(model, "ok_mass") and push_raw is not None:
        how = "simulated" if source in ("simulated", "neighbour") else "analytic"
        summary += f"\nshare of drops that leave without jamming ({how}): {float(model.ok_mass(push_raw)[0]):.2f}"
    print(summary, file=sys.stdout if args.out is not None else sys.stderr)
    if args.plot is not None:
        from feeder.io import save_figure

        name = (args.part or args.features).stem
        outline, holes = None, ()
        if args.part is not None and args.part.suffix.lower() == ".stl":
            from feeder.parts.geometry import load_profile

            outline, holes, _ = load_profile(args.part, "auto")
        title = f"{model.spec.name}: {name}, loc1 {args.loc1}, loc2 {args.loc2}"
        save_figure(args.plot, plot(frame, title, outline, holes))
    push_ms = "" if push_raw is None and analytic is None else f", push features {1e3 * (t1 - t_dft):.1f} ms"
    print(
        f"feeder predict: features {1e3 * (t_dft - t0):.1f} ms{push_ms}, answer {1e3 * (t2 - t1):.1f} ms",
        file=sys.stderr,
    )
    return 0
