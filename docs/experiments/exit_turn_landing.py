"""Would finding the landing within the step cure the exit turn's fragility? (hard cases; no)

``docs/experiments/exit_turn_fragility.py`` found the analytic exit turn fragile: keyhole-c's edge 5
on a 40-degree fence is "hooked" at most angles near 40 but "released" at scattered ones. One
suspect: in the corner phase (``_Exit.corner``) a vertex that lands on the fence face is noticed
only after a whole integration step, and the next phase (``_Exit.both``) calls it caught on the
corner when it lies within ``EXIT_HOOK_TOL`` of the corner's contact. This script replaces
``_Exit.corner`` (monkeypatched here only; the package is unchanged) by a copy that, once a step
lands a vertex, bisects the step (``BISECTIONS`` halvings of the midpoint rule from the state before
it) to the fraction where that vertex first touches the face, and hands the next phase that state.
It prints the outcomes (``H`` hooked, ``r`` released, ``p`` phases, ``w`` wedged) at 81 angles within
2e-6 degrees of 40 and at 101 within 0.5 degrees, as the code is and bisected:

    python docs/experiments/exit_turn_landing.py PARTS_DIR

Seconds; reads no simulation. If the scatter remains, the corner landing is not its (only) cause.
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads: OpenBLAS's AVX2 kernel (feeder/__init__.py)

# isort: on
import sys
from pathlib import Path

import numpy as np

import feeder.mechanics.exitturn as E
from feeder.mechanics.fence import default_scene, fence_models, fence_mu
from feeder.mechanics.hull import as_geometry
from feeder.parts.geometry import load_part

BISECTIONS = 48  # halvings of a step: its fraction to ~4e-15
ORIGINAL_CORNER = E._Exit.corner


def bisecting_corner(self, k: int, s: float):
    """``_Exit.corner`` with the landing found within the step (module doc); otherwise the same."""
    self.phases += "C"
    P, n = self.poly, self.n
    switches = 0
    while True:
        a = P[k]
        e = P[(k + 1) % n] - a
        length = float(np.hypot(*e))
        e = e / length

        def deriv(yaw, s, a=a, e=e):
            R = self.rot(yaw)
            ew = R @ e
            r = R @ (a + s * e)
            tw = E._contact_twist(r[0], r[1], -ew[1], ew[0], ew[0], ew[1], self.mu, self.c2)
            if tw is None:
                return None
            vx, vy, w = tw
            rel = np.array(E._PUSHER_VELOCITY) - np.array([vx - w * r[1], vy + w * r[0]])
            return w, float(rel @ ew)

        def advance(yaw, s, h):
            k1 = deriv(yaw, s)
            k2 = None if k1 is None else deriv(yaw + 0.5 * h * k1[0], s + 0.5 * h * k1[1])
            return None if k2 is None else (yaw + h * k2[0], s + h * k2[1])

        while self.steps_left > 0:
            self.steps_left -= 1
            before = (self.yaw, s, self.passed.copy())
            k1 = deriv(self.yaw, s)
            if k1 is None:
                return self.release(k, s, "released")
            k2 = deriv(self.yaw + 0.5 * self.step * k1[0], s + 0.5 * self.step * k1[1])
            if k2 is None:
                return self.release(k, s, "released")
            self.yaw += self.step * k2[0]
            s += self.step * k2[1]
            if not 0.0 <= s <= length:
                break
            self.X = -(self.rot() @ (a + s * e))
            pts = self.world()
            hit = self.landed(pts)
            if hit.any():  # an upstream vertex meets the face: find where within the step
                v = int(np.argmin(np.where(hit, pts @ self.nf, np.inf)))
                yaw0, s0, _ = before
                lo, hi = 0.0, self.step
                for _ in range(BISECTIONS):
                    mid = 0.5 * (lo + hi)
                    state = advance(yaw0, s0, mid)
                    if state is None:
                        lo = mid
                        continue
                    X = -(self.rot(state[0]) @ (a + state[1] * e))
                    depth = float((X + self.rot(state[0]) @ P[v]) @ self.nf)
                    lo, hi = (mid, hi) if depth > 0.0 else (lo, mid)
                state = advance(yaw0, s0, hi)
                if state is not None and 0.0 <= state[1] <= length:
                    self.yaw, s = state
                    self.X = -(self.rot() @ (a + s * e))
                    self.passed = before[2]  # the tip passes as of the landing, not of the whole step
                    self.landed(self.world())
                return ("B", v, k, s)
        else:
            return self.release(k, s, "travel")
        switches += 1
        j = (k + 1) % n if s > length else k
        if not self.geom.convex[j] or switches > 2 * n:
            return self.release(k, min(max(s, 0.0), length), "notch")
        k, s = (j, 0.0) if s > length else ((k - 1) % n, float(np.hypot(*(P[k] - P[(k - 1) % n]))))


def use(bisect: bool) -> None:
    """The corner phase as it is, or bisecting the landing."""
    E._Exit.corner = bisecting_corner if bisect else ORIGINAL_CORNER


def main(argv: list[str]) -> int:
    parts_dir = Path(argv[0])
    scene = default_scene()
    geom = as_geometry(load_part(parts_dir / "keyhole-c.stl", "auto"))
    side, mu = fence_models("none", "straight:40", scene)[0].side, fence_mu(scene)
    for bisect in (False, True):
        use(bisect)
        for span, n in ((2e-6, 81), (0.5, 101)):
            marks = "".join(
                {"hooked": "H", "released": "r"}.get(t.reason, t.reason[0])
                for t in (E.exit_turn(geom, 5, 40.0 + d, side, mu) for d in np.linspace(-span, span, n))
            )
            print(f"keyhole-c edge 5, 40 +- {span:g} deg, {'bisected' if bisect else 'as is'}: {marks}")
    use(False)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
