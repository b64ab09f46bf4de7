"""One cold answer of ``feeder predict``, timed step by step in a fresh interpreter: the child
process of ``feeder bench-predict`` (:mod:`feeder.bench.predict`), run as a script so that nothing
is imported before its clock starts.

    python predict_probe.py MODEL PART LOC1 LOC2

Prints one JSON object of milliseconds: ``import`` (the predict command's module: numpy, pandas),
``model_load`` (the weights, read for numpy, :func:`feeder.learn.predict.load_model`),
``features_cold`` (the process's first features from the part file: the feature path's own lazy
imports, OpenCV and shapely, plus the computation) and ``config_cold`` (the first prediction of one
fence configuration: the label and fence modules' imports plus the network).
"""

import json
import sys
import time


def main(argv: list[str]) -> dict[str, float]:
    model_dir, part, loc1, loc2 = argv
    from pathlib import Path

    clock = [time.perf_counter()]
    ms: dict[str, float] = {}

    def lap(stage: str) -> None:
        now = time.perf_counter()
        ms[stage] = 1e3 * (now - clock[0])
        clock[0] = now

    from feeder.learn.predict import load_model, part_vector, predict_frame

    lap("import")
    model = load_model(Path(model_dir))
    lap("model_load")
    part_raw, frame_deg = part_vector(Path(part), None)
    lap("features_cold")
    predict_frame(model, part_raw, loc1, loc2, frame_deg)
    lap("config_cold")
    return ms


if __name__ == "__main__":
    print(json.dumps(main(sys.argv[1:])))
