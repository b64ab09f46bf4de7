"""The decomposition test: how far each contact model's labels move with the part's convex pieces.

Data: ``results/tables/contact_decomposition.csv`` (``feeder bench-decomposition``): one row per
part, configuration, contact model and pair of decompositions (``kind = decomposition``) with the
paired median |Δ final yaw| and the labels' circular W1, each beside the model's floor
(``floor_*``), and one ``verdict`` row per model with its CPU per drop. Left: median |Δyaw| between
decompositions (filled) and the floor (open), per model, log scale. Middle: the same for the
labels' circular W1. Right: CPU per drop of each model, with its verdicts on top (rows passed out of rows).
"""

from __future__ import annotations

import re

import numpy as np

from feeder.figures import style

COLUMNS = (
    "kind",
    "part",
    "model",
    "median_dyaw_deg",
    "circular_w1_deg",
    "floor_median_dyaw_deg",
    "floor_circular_w1_deg",
    "passes",
    "passes_paired",
    "passes_label",
    "cpu_ms_per_drop",
    "rows",
    "rows_passed_paired",
    "rows_passed_label",
)
_FLOOR_AT_LEAST = 1e-4  # deg: where a floor or a distance of zero is drawn on the log axes


def model_order(name: str) -> tuple[str, int, int]:
    """Pieces first, then pad models by what meets walls and fences (``+outline``), by pad count."""
    hit = re.fullmatch(r"pads([1-9][0-9]*)(.*)", name)
    return ("", 0, 0) if hit is None else (hit.group(2), 1, int(hit.group(1)))


def tick(name: str) -> str:
    """A model's tick label: a wall-contact suffix on its own line."""
    return name.replace("+", "\n+")


def _truthy(value) -> bool:
    return str(value).strip().lower() in ("true", "1", "1.0")


def draw(table):
    rows = table[table["kind"] == "decomposition"]
    verdicts = table[(table["kind"] == "verdict") & (table["model"].isin(rows["model"].unique()))]
    models = sorted(rows["model"].unique(), key=model_order)
    parts = sorted(rows["part"].unique())
    colours = dict(
        zip(parts, ["tab:blue", "tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:olive"] * 4, strict=False)
    )
    fig, (paired, label, cost) = style.subplots(1, 3, figsize=(max(13.0, 2.2 * len(models) + 2.0), 4.2))
    rng = np.random.default_rng(0)  # horizontal jitter only
    for ax, col, title in (
        (paired, "median_dyaw_deg", "Paired: median |Δ final yaw|"),
        (label, "circular_w1_deg", "Label: circular W1"),
    ):
        for k, model in enumerate(models):
            sub = rows[rows["model"] == model]
            for part in parts:
                p = sub[sub["part"] == part]
                if p.empty:
                    continue
                x = k + rng.uniform(-0.08, 0.08, len(p))
                cross = np.maximum(p[col].to_numpy(float), _FLOOR_AT_LEAST)
                floor = np.maximum(p[f"floor_{col}"].to_numpy(float), _FLOOR_AT_LEAST)
                ax.plot([x - 0.15, x + 0.15], [cross, floor], "-", color=colours[part], lw=0.5, alpha=0.5)
                ax.plot(x - 0.15, cross, "o", color=colours[part], ms=4, label=part if k == 0 else None)
                ax.plot(x + 0.15, floor, "o", mfc="none", color=colours[part], ms=5)
        ax.set_yscale("log")
        ax.set_xticks(range(len(models)), [tick(m) for m in models], fontsize=7)
        ax.set_ylabel("degrees: filled across decompositions,\nopen the model's floor", fontsize=8)
        ax.set_title(title)
        ax.grid(True, axis="y")
    paired.legend(fontsize=7, loc="lower left")
    by_model = {v["model"]: v for _, v in verdicts.iterrows()}
    heights = [float(by_model[m]["cpu_ms_per_drop"]) if m in by_model else np.nan for m in models]
    bars = cost.bar(range(len(models)), heights, color=style.PALETTE["neutral"])
    for k, (bar, model) in enumerate(zip(bars, models)):
        v = by_model.get(model)
        if v is None:
            continue
        text = "\n".join(
            f"{what} {'pass' if _truthy(v[f'passes_{what}']) else 'fail'} "
            f"({int(v[f'rows_passed_{what}'])}/{int(v['rows'])} rows pass)"
            for what in ("paired", "label")
        )
        cost.text(k, bar.get_height(), text, ha="center", va="bottom", fontsize=5)
    cost.set_xticks(range(len(models)), [tick(m) for m in models], fontsize=7)
    cost.set_ylabel("CPU per drop (ms)")
    cost.set_title("Cost, and the verdict across decompositions")
    cost.margins(y=0.25)
    return fig


def main(argv: list[str]) -> int:
    args = style.parser(
        "contact_decomposition", __doc__, "the decomposition test (contact_decomposition.csv)"
    ).parse_args(argv)
    style.save(draw(style.read_csv(args.data, COLUMNS)), args.out)
    return 0
