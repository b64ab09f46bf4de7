"""Which calibration mode answers each scored row of the Main fits, and what it gains (stop 73).

The protocol's own choice (:func:`feeder.learn.structured_calibration.with_calibration` on each Main
fit's training rows, ``config/hydra/structured.yaml``'s ``calibration``), per Test and Fences row of
each repeat: the chosen mode and the circular W1 of the analytic model and of that mode. Prints
the modes' counts and the per-part means; needs the cached mode PMFs
(``results/datasets/structured_calibration.npz``, else about 20 minutes to compute them):

    python docs/experiments/calibration_by_part.py results/tables/calibration_by_part.csv
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from feeder import io
from feeder.config import compose_config
from feeder.labels.dataset import load_dataset
from feeder.learn.structured_calibration import calibration_settings, with_calibration
from feeder.learn.structured_data import structured_arrays
from feeder.learn.structured_protocol import protocol_jobs


def main(argv: list[str]) -> int:
    out_csv = Path(argv[0])
    cfg = compose_config("structured", ["protocol.fits=[main]"])
    modes, margin = calibration_settings(cfg)
    names = ["base"] + [m.name for m in modes]
    data = load_dataset("results/datasets/dataset.npz")
    cache = "results/datasets/structured_candidates.npz"
    a = structured_arrays(data, cfg, "results/sim", "parts", "results/features", cache, calibration=True)
    rows = []
    for _kind, _key, repeat, train, scored in protocol_jobs(a, cfg)[0]:
        c = with_calibration(a, train, margin)
        for experiment, mask in scored.items():
            for i in np.flatnonzero(mask & a["kept"]):
                m = int(c["calibration_mode"][i])
                rows.append(
                    {
                        "experiment": experiment,
                        "repeat": repeat,
                        "part": a["part"][i],
                        "config_id": a["config_id"][i],
                        "mode": names[m],
                        "w1_base": a["mode_w1"][i, 0],
                        "w1_calibrated": a["mode_w1"][i, m],
                    }
                )
    d = pd.DataFrame(rows)
    io.write_csv(out_csv, d)
    for experiment in ("test", "fences"):
        e = d[d.experiment == experiment]
        g = e.groupby("part").agg(
            rows=("mode", "size"),
            modes=("mode", lambda s: ",".join(sorted(set(s)))),
            base=("w1_base", "mean"),
            calibrated=("w1_calibrated", "mean"),
        )
        g["gain"] = g.calibrated - g.base
        print(experiment, e["mode"].value_counts().to_dict())
        print(g.sort_values("gain").round(2).to_string())
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
