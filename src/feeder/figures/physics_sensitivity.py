"""How far the labels move with the physics, against the label's noise floor and the models' error.

Data: ``results/tables/physics_sensitivity.csv`` (``feeder bench-physics``): one ``factor`` row per
factor with the median over the configurations of each label shift and its 95 % bootstrap interval,
a ``floor`` row (the label's own noise: the baseline at a second offset of the design, or nudged by
0.01°) and ``model_error`` rows (the circular W1 of the models' predictions, from committed tables).
Left: circular W1 between each factor's label and the baseline's (median and interval, log scale),
the floor shaded, the models' errors dashed. Middle: each configuration's shift over its own floor,
median and interval (1: the shift is the label's own noise). Right: the paired same-basin fraction
(drops that end in the same basin as under the baseline), the floor shaded.
"""

from __future__ import annotations

import numpy as np

from feeder.figures import style

COLUMNS = (
    "kind",
    "factor",
    "circular_w1_deg_median",
    "circular_w1_deg_median_low",
    "circular_w1_deg_median_high",
    "circular_w1_deg_mean",
    "same_basin_median",
    "same_basin_median_low",
    "same_basin_median_high",
    "circular_w1_to_floor_median",
    "circular_w1_to_floor_median_low",
    "circular_w1_to_floor_median_high",
)
_LEAST_DEG = 0.01  # deg: where a shift of zero is drawn on the log axis
_LINES = ("--", "-.", ":", (0, (5, 1, 1, 1)))


def draw(table):
    factors = table[table["kind"] == "factor"].reset_index(drop=True)
    floor = table[table["kind"] == "floor"]
    errors = table[table["kind"] == "model_error"]
    fig, (w1, ratio, basin) = style.subplots(1, 3, figsize=(15, 0.35 * len(factors) + 3.0), sharey=True)
    y = np.arange(len(factors))[::-1]
    for ax, col, least in (
        (w1, "circular_w1_deg", _LEAST_DEG),
        (ratio, "circular_w1_to_floor", _LEAST_DEG),
        (basin, "same_basin", None),
    ):
        mid = factors[f"{col}_median"].to_numpy(float)
        low = factors[f"{col}_median_low"].to_numpy(float)
        high = factors[f"{col}_median_high"].to_numpy(float)
        if least is not None:
            mid, low, high = (np.maximum(v, least) for v in (mid, low, high))
        ax.errorbar(mid, y, xerr=[mid - low, high - mid], fmt="o", color=style.PALETTE["primary"], capsize=3)
        if not floor.empty and ax is not ratio:
            f = floor.iloc[0]
            lo, hi = float(f[f"{col}_median_low"]), float(f[f"{col}_median_high"])
            if least is not None:
                lo, hi = max(lo, least), max(hi, least)
            ax.axvspan(lo, hi, color=style.PALETTE["neutral"], alpha=0.35, label="label noise floor (95 % interval)")
            ax.axvline(max(float(f[f"{col}_median"]), least or -np.inf), color=style.PALETTE["muted"], lw=1)
        ax.grid(True, axis="x")
    for k, (_, e) in enumerate(errors.iterrows()):
        w1.axvline(
            float(e["circular_w1_deg_mean"]),
            color=style.PALETTE["reference"],
            ls=_LINES[k % len(_LINES)],
            lw=1,
            label=f"{e['factor']}: {float(e['circular_w1_deg_mean']):.1f}°",
        )
    w1.set_xscale("log")
    w1.set_yticks(y, factors["factor"])
    w1.set_xlabel("circular W1 to the baseline's label (deg)")
    w1.set_title("Label shift")
    w1.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2)
    ratio.axvline(1.0, color=style.PALETTE["reference"], lw=1, label="shift = the configuration's floor")
    ratio.set_xscale("log")
    ratio.set_xlabel("circular W1 shift / the configuration's floor")
    ratio.set_title("Shift over the label's own noise")
    ratio.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.1))
    basin.set_xlim(-0.02, 1.02)
    basin.set_xlabel("fraction of drops in the baseline's basin")
    basin.set_title("Paired drop by drop")
    basin.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.1))
    fig.suptitle("Medians over the configurations, 95 % bootstrap intervals", fontsize=9)
    return fig


def main(argv: list[str]) -> int:
    args = style.parser(
        "physics_sensitivity", __doc__, "the physics sensitivity table (physics_sensitivity.csv)"
    ).parse_args(argv)
    style.save(draw(style.read_csv(args.data, COLUMNS)), args.out)
    return 0
