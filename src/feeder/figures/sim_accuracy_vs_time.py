"""Simulation accuracy against time: distance of each simulation setting's yaw distribution to the
reference setting's against its CPU cost per drop (left, middle: JS and W1 at the full drop count,
with the two-seed noise floor and the Pareto front), and the distance against drops per
configuration (right).

Data: ``results/tables/sim_accuracy_vs_time.csv`` (``feeder bench-sim``): rows per setting, drop
count and panel configuration plus ``config == "mean"`` rows (used here) with ``ms_per_drop``,
``js``, ``js_floor``, ``w1_deg``, ``w1_floor_deg``, ``within_floor``. ``--reference`` names the
reference setting (``sim.bench.reference``).
"""

from __future__ import annotations

import numpy as np

from feeder.figures import style

COLUMNS = ("setting", "drops", "config", "ms_per_drop", "js", "js_floor", "w1_deg", "w1_floor_deg", "within_floor")


def draw(df, ref_name: str):
    agg = df[df["config"] == "mean"]
    full = agg[agg["drops"] == agg["drops"].max()]
    fig, axes = style.subplots(1, 3, figsize=(17, 4.8))
    for ax, col, floor, label in [
        (axes[0], "js", "js_floor", "JS divergence to reference (bits)"),
        (axes[1], "w1_deg", "w1_floor_deg", "W1 on the CDF to reference (deg)"),
    ]:
        fl = full[floor].mean()
        ax.axhspan(0, fl, color="0.85", label=f"two-seed noise floor ({fl:.3g})")
        for _, r in full.iterrows():
            mk = "*" if r["setting"] == ref_name else "o"
            ax.scatter(
                r["ms_per_drop"],
                r[col],
                marker=mk,
                s=60 if mk == "*" else 30,
                color="C3" if not r["within_floor"] else "C0",
                zorder=3,
            )
            ax.annotate(r["setting"], (r["ms_per_drop"], r[col]), fontsize=7, xytext=(3, 3), textcoords="offset points")
        # Pareto front: no other setting both cheaper and closer
        best, front = np.inf, []
        for _, r in full.sort_values("ms_per_drop").iterrows():
            if r[col] < best:
                best = r[col]
                front.append((r["ms_per_drop"], r[col]))
        if front:
            fx, fy = zip(*front)
            ax.step(fx, fy, where="post", color="C2", lw=1, label="Pareto front")
        ax.set_xscale("log")
        ax.set_xlabel("CPU ms per drop (log)")
        ax.set_ylabel(label)
        ax.legend(fontsize=7)
    # drops per configuration: the distance of the fast preset and of the floor against k
    ax = axes[2]
    for name, fmt in [("fast", "o-"), (ref_name, "s--")]:
        sub = agg[agg["setting"] == name].sort_values("drops")
        if len(sub):
            ax.plot(
                sub["drops"],
                sub["js"],
                fmt,
                label=f"{name} vs reference" if name != ref_name else "noise floor (reference, second seed)",
            )
    ax.set_xlabel("drops per configuration")
    ax.set_ylabel("JS divergence to reference (bits)")
    ax.legend(fontsize=7)
    fig.suptitle(
        f"Simulation accuracy against time ({int(full['drops'].max())} drops per configuration, "
        f"{df[df['config'] != 'mean']['config'].nunique()} configurations; "
        "blue = inside the noise floor by the paired test, red = outside)"
    )
    fig.tight_layout()
    return fig


def main(argv: list[str]) -> int:
    ap = style.parser("sim_accuracy_vs_time", __doc__, "sim_accuracy_vs_time.csv")
    ap.add_argument("--reference", required=True, help="the reference setting's name (sim.bench.reference)")
    args = ap.parse_args(argv)
    style.save(draw(style.read_csv(args.data, COLUMNS), args.reference), args.out)
    return 0
