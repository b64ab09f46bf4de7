"""Figure: the fence tip, square or round, and the analytic model's corner or disc (issue #39).

Left: the traced drop of ``docs/experiments/fence_tip.py`` (rect-a3 on ``straight:60`` from
141.1°, raw rows ``results/tables/fence_tip_trace.csv``): the part's yaw against time with a
square and a round tip, and the analytic exit yaws of the corner and disc models (modulo the
part's 180° symmetry). Right: per configuration, the share of the 16 round-tip drops that agree
with the analytic model, corner against disc (``results/tables/round_tip_model.csv`` from
``docs/experiments/round_tip_model.py``), by group.

    python docs/experiments/round_tip_figure.py results/tables OUT_PNG
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads: OpenBLAS's AVX2 kernel (feeder/__init__.py)

# isort: on
import copy
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from feeder.io import write_bytes  # noqa: E402
from feeder.mechanics.distribution import fence_response  # noqa: E402
from feeder.mechanics.fence import default_scene, fence_models, fence_mu  # noqa: E402
from feeder.mechanics.hull import as_geometry  # noqa: E402
from feeder.parts.geometry import load_part  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
PART, FENCE = "rect-a3", "straight:60"
GROUPS = ("one steep straight", "one, other", "two fences")
COLOURS = {"one steep straight": "tab:red", "one, other": "tab:blue", "two fences": "tab:green"}


def exits() -> dict:
    square = copy.deepcopy(default_scene())
    square["fences"].pop("tip", None)
    rounded = copy.deepcopy(square)
    rounded["fences"]["tip"] = "round"
    geom = as_geometry(load_part(ROOT / "parts" / f"{PART}.stl"))
    out = {}
    for name, scene in (("corner", square), ("disc", rounded)):
        model = fence_models(FENCE, "none", scene)[0]
        out[name] = fence_response(geom, model, fence_mu(scene)).exit_deg % 180.0
    return out


def main(argv: list[str]) -> int:
    tables, out_png = Path(argv[0]), Path(argv[1])
    trace = pd.read_csv(tables / "fence_tip_trace.csv")
    drops = pd.read_csv(tables / "round_tip_model.csv")
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.2))
    for tip, colour in (("square", "tab:gray"), ("round", "tab:purple")):
        t = trace[trace.tip == tip].drop_duplicates("t_s")
        ax.plot(t.t_s, t.yaw_deg % 180.0, color=colour, label=f"simulated, {tip} tip")
    for (name, yaws), style in zip(exits().items(), ("--", ":")):
        for y in np.unique(np.round(yaws, 6)):
            ax.axhline(y, color="black", ls=style, lw=1, label=f"analytic exit, {name} model ({y:.1f}°)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("yaw modulo 180° (deg)")
    ax.set_title(f"{PART} on {FENCE}, one drop from 141.1°")
    ax.legend(fontsize=8)
    per = drops.dropna(subset=["corner_agrees"]).groupby(["group", "part", "config_id"])
    agree = per[["corner_agrees", "disc_agrees"]].mean().reset_index()
    rng = np.random.default_rng(0)
    for g in GROUPS:
        a = agree[agree.group == g]
        jitter = rng.uniform(-0.01, 0.01, size=(2, len(a)))
        bx.scatter(
            a.corner_agrees + jitter[0],
            a.disc_agrees + jitter[1],
            s=14,
            alpha=0.6,
            color=COLOURS[g],
            label=f"{g} ({len(a)}): {a.corner_agrees.mean():.2f} → {a.disc_agrees.mean():.2f}",
        )
    bx.plot([0, 1], [0, 1], color="black", lw=0.8)
    bx.set_xlabel("drops that agree, corner model")
    bx.set_ylabel("drops that agree, disc model")
    bx.set_title("round-tip drops, 16 per configuration")
    bx.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    out_png.parent.mkdir(parents=True, exist_ok=True)
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    write_bytes(out_png, buf.getvalue())
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
