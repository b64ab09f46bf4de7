"""feeder bench-contact: the belt footprint's pieces against pads, the same drops paired."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from feeder.bench import contact
from feeder.config import load_study_config

CONFIG = load_study_config(root=__import__("pathlib").Path(__file__).resolve().parents[1])


def _raw():
    """Two drops of one part and configuration under three footprints: pads8 moves drop 1 into
    another basin (+90 deg), pads16 moves drop 0 by 0.4 deg. Nudged twins: the pieces' drop 1
    moves by 3 deg, pads16's by 0.1 deg (its drop 0 not at all); pads8 has none."""
    rows = []
    finals = {"pieces": [10.0, 200.0], "pads8": [10.2, 290.0], "pads16": [10.4, 200.0]}
    twins = {"pieces": [10.0, 203.0], "pads16": [10.4, 200.1]}
    cpu = {"pieces": 2.0, "pads8": 0.4, "pads16": 0.6}
    for shift, runs in ((0.0, finals), (0.01, twins)):
        for fp, ys in runs.items():
            for i, y in enumerate(ys):
                rows.append(
                    {
                        "part": "p",
                        "configuration": "a|b",
                        "footprint": fp,
                        "yaw_shift_deg": shift,
                        "drop": i,
                        "final_yaw_deg": y,
                        "status": "ok",
                        "cpu_s": cpu[fp] * (1 + shift),
                    }
                )
    return pd.DataFrame(rows)


def test_summary_pairs_each_footprint_with_the_pieces_and_the_reference():
    table = contact.summarize(_raw(), {"p": 30}, "pads16").set_index("footprint")
    assert table.loc["pieces", "cpu_ms_per_drop"] == pytest.approx(1000.0)  # 2 s over 2 drops
    assert table.loc["pads8", "cpu_ms_per_drop"] == pytest.approx(200.0)
    assert table.loc["pads8", "same_basin_vs_pieces"] == 0.5
    assert table.loc["pads8", "median_dyaw_vs_pieces_deg"] == pytest.approx(0.2)
    assert table.loc["pads8", "same_basin_vs_reference"] == 0.5
    assert table.loc["pads16", "same_basin_vs_pieces"] == 1.0
    assert table.loc["pads16", "median_dyaw_vs_pieces_deg"] == pytest.approx(0.2)  # median of 0.4 and 0
    assert table.loc["pads16", "same_basin_vs_reference"] == 1.0
    assert table.loc["pads16", "median_dyaw_vs_reference_deg"] == 0.0
    assert (table["pieces"] == 30).all() and (table["drops"] == 2).all()
    # the floor: each footprint against its own nudged twins
    assert table.loc["pieces", "same_basin_vs_nudged"] == 1.0
    assert table.loc["pieces", "median_dyaw_vs_nudged_deg"] == pytest.approx(1.5)
    assert table.loc["pads16", "median_dyaw_vs_nudged_deg"] == pytest.approx(0.05)
    assert np.isnan(table.loc["pads8", "same_basin_vs_nudged"])  # no twins: no floor


def test_footprint_scene_sets_the_model_and_the_pad_count():
    scene = {"belt": {"speed": 0.1}, "part": {"wall_contact": {"model": "outline", "depth": 0.002}}}
    assert contact.footprint_scene(scene, "pads24", 0.002)["part"]["wall_contact"] == {
        "model": "pieces",
        "depth": 0.002,
    }
    assert contact.footprint_scene(scene, "pads24", 0.002)["belt"]["footprint"] == {
        "model": "pads",
        "pads": 24,
        "pad_radius": 0.002,
    }
    assert contact.footprint_scene(scene, "pieces", 0.002)["belt"]["footprint"]["model"] == "pieces"
    assert "footprint" not in scene["belt"] and scene["part"]["wall_contact"]["model"] == "outline"  # left alone


@pytest.mark.parametrize(
    "missing, needle",
    [
        (None, "8 convex pieces or more"),  # a library of one square (one piece) against min_pieces 8
        ("presets", "presets"),  # a missing section: one line, no traceback
    ],
)
def test_bench_contact_refuses_a_bad_library_or_settings_in_one_line_writing_nothing(tmp_path, capsys, missing, needle):
    import json

    from feeder.cli import main
    from feeder.parts.geometry import stl_bytes

    (tmp_path / "parts").mkdir()
    (tmp_path / "parts" / "sq.stl").write_bytes(
        stl_bytes(np.array([[0, 0], [0.02, 0], [0.02, 0.02], [0, 0.02]]), 0.005)
    )
    settings = {
        "scene": {"belt": {"footprint": {"model": "pieces", "pads": 1, "pad_radius": 0.001}}},
        "sim": {
            "presets": CONFIG["sim"]["presets"],
            "base_seed": 0,
            "contact_bench": {
                "min_pieces": 8,
                "configurations": ["straight:30|none"],
                "drops": 1,
                "pads": [4],
                "nudge_deg": 0.01,
                "preset": "fast",
                "workers": 1,
            },
        },
        "parts": {"dir": str(tmp_path / "parts")},
    }
    if missing is not None:
        del settings["sim"][missing]
    out = tmp_path / "t.csv"
    argv = ["bench-contact", "--settings", json.dumps(settings), "--out-csv", str(out)]
    code = main([*argv, "--out-raw", str(tmp_path / "r.csv")])
    assert code == 2 and needle in capsys.readouterr().err and not out.exists()
