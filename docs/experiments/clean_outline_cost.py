"""What dropping collinear vertices costs: one scan against a rescan after every removal (2026-11-28)

A new user's 16,000-facet round part took 26 s in ``feeder predict``, nearly all of it in
``feeder.parts.geometry.clean_outline``, which rescanned the whole outline after removing each
collinear vertex. It now scans once (``_drop_collinear``), with the same arithmetic, and gives the
same outline to the bit (``tests/test_geometry.py``, whose ``_clean_outline_by_rescans`` is the old
rule and is timed here). This script times both on faceted circles of 1,000 to 16,000 vertices
(every facet within the tolerance of its chord, so most are removed) and on every part in
``parts/`` read as ``feeder predict`` reads it (``load_profile``), and counts the square roots each
the vertex-by-vertex scan takes (one per vertex test or removal, a machine-independent measure of
its work; the old rule's tests are vectorised numpy and count 0 here).

    python docs/experiments/clean_outline_cost.py results/tables/clean_outline_cost.csv [REPEATS]

One raw row per case, implementation and repeat: wall seconds, square roots, vertices in and out,
and whether the two outlines are equal to the bit.
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads: OpenBLAS's AVX2 kernel (feeder/__init__.py)

# isort: on
import math
import sys
import time
import unittest.mock as mock
from pathlib import Path

import numpy as np
import pandas as pd

from feeder import io
from feeder.parts import geometry as G

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))
from test_geometry import _clean_outline_by_rescans  # noqa: E402  (the old rule, kept as the tests' oracle)

FACETS = (1000, 2000, 4000, 8000, 16000)
RADIUS_M = 0.02  # a 40 mm round part


def faceted_circle(n: int) -> np.ndarray:
    t = np.linspace(0.0, 2 * np.pi, n + 1)[:-1]
    return RADIUS_M * np.column_stack([np.cos(t), np.sin(t)])


def timed(fn, *args):
    """(result, wall seconds, square roots the scan took) of fn(*args): timed bare, then counted in
    a second call (the counting wrapper would weigh on the scan's time alone)."""
    t0 = time.perf_counter()
    out = fn(*args)
    wall = time.perf_counter() - t0
    with mock.patch.object(G.math, "sqrt", wraps=math.sqrt) as sqrt:
        fn(*args)
    return out, wall, sqrt.call_count


def main(argv: list[str]) -> int:
    out = Path(argv[0])
    repeats = int(argv[1]) if len(argv) > 1 else 3
    cases = [(f"circle-{n}", faceted_circle(n)) for n in FACETS]
    raw = {}  # the outlines load_profile hands to clean_outline, per part
    real = G.clean_outline
    for path in sorted((ROOT / "parts").glob("*.stl")):

        def capture(outline, *a, _name=path.stem, **k):
            raw.setdefault(_name, np.array(outline, dtype=np.float64))
            return real(outline, *a, **k)

        with mock.patch.object(G, "clean_outline", capture):
            G.load_profile(path, "auto")
    cases += [(f"part-{name}", outline) for name, outline in raw.items()]
    rows = []
    for repeat in range(repeats):
        for name, outline in cases:
            new, wall_new, roots_new = timed(G.clean_outline, outline)
            old, wall_old, roots_old = timed(_clean_outline_by_rescans, outline)
            same = new.tobytes() == old.tobytes()
            for impl, wall, roots in (("one scan", wall_new, roots_new), ("rescans", wall_old, roots_old)):
                rows.append(
                    {
                        "case": name,
                        "implementation": impl,
                        "repeat": repeat,
                        "wall_s": wall,
                        "square_roots": roots,
                        "vertices_in": len(outline),
                        "vertices_out": len(new),
                        "bit_identical": same,
                    }
                )
        print(f"repeat {repeat + 1}/{repeats} done", file=sys.stderr, flush=True)
    table = pd.DataFrame(rows)
    io.write_csv(out, table)
    med = table.groupby(["case", "implementation"]).wall_s.median().unstack()
    circles = [f"circle-{n}" for n in FACETS]
    print(med.loc[circles].round(4).to_string())
    parts = med.drop(index=circles).sum()
    print(f"all {len(raw)} parts, summed medians: one scan {parts['one scan']:.3f} s, rescans {parts['rescans']:.3f} s")
    print(f"bit-identical: {bool(table.bit_identical.all())} over {table.case.nunique()} cases")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
