"""The exit turn: how a part turns as it leaves the tip of a fence.

Leaving a fence (:func:`exit_turn`)
    Past the fence tip the part does not stay flush: measured on the design bench's 2,880-yaw
    references (``results/bench/designs``), a 2:1 rectangle flush at 135° on a 45° fence ends at
    100°. The exit is integrated as quasi-static pushing of the actual outline by the fence (belt
    frame: the fence moves at ``−y``), with the ellipsoidal limit surface
    ``(v, ω) ∝ (F, (r × F) / c²)`` and every contact sliding on the friction-cone edge that
    opposes its slip or sticking inside the cone (Lynch, Maekawa & Tanie 1992). Phases:
    *flush* (sliding, no turn) until the foot shifted ``mu·d`` leaves the part of the face still
    under the part; then *C*, the tip corner on an outline edge (the edge turns about the corner
    towards the travel direction until the corner slides off its end or onto the next convex
    edge); *F*, where the hull edge bridges a concavity (a star's two tips, a keyhole's stem and
    head), the last supported vertex pivoting on the face until it passes the tip or another
    vertex lands (flush again; rolling on a polygonal curve); *B*, both at once (a keyhole's stem
    on the face while its head rolls over the corner). After the corner lets go, the part rides
    the belt and meets the corner again if that path hits its outline. Not modelled, and where
    the integration stops with the part as it is: the fence's end face (a star's tip swinging
    back behind the tip), a corner caught in a concave vertex of the outline or on a vertex lying
    on the face (a C shape open towards the fence: −50° in the simulator, ~0° here), and two
    contacts with no consistent sliding/sticking solution (*wedged*).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from feeder.errors import FeederError
from feeder.mechanics.fence import resting_yaw
from feeder.mechanics.hull import PushGeometry, as_geometry

# Exit turn integration: steps per circumradius of fence travel (midpoint rule; 200 steps move
# the exit yaws of the library parts by < 0.2° from 1,600) and the most travel integrated
# (circumradii) before giving up.
EXIT_STEPS_PER_RADIUS = 200
EXIT_MAX_TRAVEL_RADII = 20.0
EXIT_MAX_PHASES = 64  # flush / pivot / corner phases followed before giving up
EXIT_SAME_RAD = 1e-9  # two flush states this close in yaw (radians) are the same state
# Distance (of the circumradius) within which an outline vertex counts as on the fence face.
EXIT_CONTACT_TOL = 1e-6
# How far (of the circumradius) a vertex is moved past the tip when it leaves the face.
EXIT_PASS_MARGIN = 1e-4
# A vertex on the face this close (of the circumradius) to the corner's contact is caught on it.
EXIT_HOOK_TOL = 1e-2
# Pusher (fence corner) velocity relative to the belt: the belt carries the part along +y.
_PUSHER_VELOCITY = (0.0, -1.0)


@dataclass(frozen=True)
class ExitTurn:
    """How a part leaves a fence tip: its yaw change (degrees), the centroid's position relative
    to the tip corner when it is let go (world, metres), why the integration stopped
    (``released``: nothing pushes any more; ``stuck``: flush again where it was before;
    ``wedged``: two contacts that neither slide nor stick consistently;
    ``notch``: the corner reached a concave vertex of the outline, where it would hook (with
    ``hook``: after the hook turn, phase ``N``); ``end face``: a vertex past the tip swung back
    against the fence's end face, left out of the model; ``travel``: the travel limit) and the
    contact phases it went through (``F``: an outline vertex pivoting on the face, ``C``: the
    corner on an outline edge, ``B``: both at once, ``H``: a vertex caught on the corner, ``N``:
    the hook turn in a notch)."""

    delta_deg: float
    offset: tuple[float, float]
    reason: str
    phases: str = ""


def _contact_twist(rx, ry, nx, ny, ex, ey, mu, c2):
    """Twist ``(vx, vy, ω)`` of a part pushed at ``r`` (from its centroid, world) through a
    contact of inward normal ``n`` and tangent ``e`` by a pusher moving at ``_PUSHER_VELOCITY``
    (belt frame), quasi-static with the ellipsoidal limit surface ``(v, ω) ∝ (F, r × F / c2)``;
    the contact sticks when the pusher's velocity lies in the motion cone, else it slides on the
    friction-cone edge that opposes the slip. None when the pusher does not push."""
    vpx, vpy = _PUSHER_VELOCITY
    vpn = vpx * nx + vpy * ny
    if vpn <= 0.0:
        return None
    cand = []
    for sgn in (1.0, -1.0):
        fx, fy = nx + sgn * mu * ex, ny + sgn * mu * ey
        w = (rx * fy - ry * fx) / c2
        cand.append((sgn, fx, fy, w, fx - w * ry, fy + w * rx))
    (_, f1x, f1y, w1, c1x, c1y), (_, f2x, f2y, w2, d2x, d2y) = cand
    det = c1x * d2y - c1y * d2x
    if det != 0.0:
        k1 = (vpx * d2y - vpy * d2x) / det
        k2 = (c1x * vpy - c1y * vpx) / det
        if k1 >= 0.0 and k2 >= 0.0:  # the pusher's velocity lies in the motion cone: sticking
            return k1 * f1x + k2 * f2x, k1 * f1y + k2 * f2y, k1 * w1 + k2 * w2
    for sgn, fx, fy, w0, cx, cy in cand:
        cn = cx * nx + cy * ny
        if cn <= 0.0:
            continue
        k = vpn / cn
        if sgn * ((k * cx - vpx) * ex + (k * cy - vpy) * ey) <= 0.0:  # friction opposes the slip
            return k * fx, k * fy, k * w0
    return None  # pragma: no cover - one cone edge is always consistent


def _two_contact_twist(r1, n1, e1, r2, n2, e2, mu, c2):
    """Twist ``(vx, vy, ω)`` of a part pushed through two contacts of the same pusher (points
    ``r_i`` from the centroid, inward normals ``n_i``, tangents ``e_i``, world arrays), quasi-static
    with the ellipsoidal limit surface. Each contact either slides, its force on the friction-cone
    edge that opposes the slip, or sticks (moves with the pusher, its force inside the cone); the
    first consistent combination (sliding first) is returned, None when there is none."""
    vp = np.array(_PUSHER_VELOCITY)
    scale = np.array([1.0, 1.0, 1.0 / c2])
    contacts = ((r1, n1, e1), (r2, n2, e2))

    def col(r, f):  # the wrench of force f at r
        return np.array([f[0], f[1], r[0] * f[1] - r[1] * f[0]])

    modes = [(a, b) for a in (1.0, -1.0, 0.0) for b in (1.0, -1.0, 0.0)]  # ±: slides on that edge; 0: sticks
    for mode in sorted(modes, key=lambda m: (m[0] == 0.0) + (m[1] == 0.0)):
        cols, rows, rhs = [], [], []
        for (r, n, e), sg in zip(contacts, mode):
            if sg == 0.0:
                cols += [col(r, (1.0, 0.0)), col(r, (0.0, 1.0))]
                rows += [np.array([1.0, 0.0, -r[1]]), np.array([0.0, 1.0, r[0]])]
                rhs += [vp[0], vp[1]]
            else:
                cols.append(col(r, n + sg * mu * e))
                rows.append(col(r, n))
                rhs.append(float(n @ vp))
        bmat = np.array(cols).T * scale[:, None]  # (3, m): twists of the unknowns
        m = np.array(rows) @ bmat
        if m.shape[0] != m.shape[1] or abs(np.linalg.det(m)) < 1e-300:
            continue
        u = np.linalg.solve(m, np.array(rhs))
        tw = bmat @ u
        ok, i = True, 0
        for (r, n, e), sg in zip(contacts, mode):
            if sg == 0.0:
                f = u[i : i + 2]
                i += 2
                fn, ft = float(f @ n), float(f @ e)
                ok &= fn >= 0.0 and abs(ft) <= mu * fn + 1e-12
            else:
                slip = (np.array([tw[0] - tw[2] * r[1], tw[1] + tw[2] * r[0]]) - vp) @ e
                ok &= bool(u[i] >= 0.0) and sg * slip <= 1e-12
                i += 1
        if ok:
            return float(tw[0]), float(tw[1]), float(tw[2])
    return None


def _inside(poly: np.ndarray, p: np.ndarray) -> bool:
    """Whether point ``p`` lies inside the simple polygon ``poly`` (crossing number)."""
    a, b = poly, np.roll(poly, -1, axis=0)
    cross = (a[:, 1] > p[1]) != (b[:, 1] > p[1])
    with np.errstate(divide="ignore", invalid="ignore"):
        x = a[:, 0] + (p[1] - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    return bool(np.count_nonzero(cross & (p[0] < x)) % 2)


class _Exit:
    """The exit state machine of :func:`exit_turn` in the fence frame: tip corner at the origin,
    ``t`` the fence direction downstream, ``nf`` the face normal into the part's side; the fence
    face is the line ``p · nf = 0`` for ``p · t < 0``. The part's pose is its centroid ``X`` and
    yaw; the pusher moves at ``_PUSHER_VELOCITY`` relative to the belt."""

    def __init__(
        self,
        geom: PushGeometry,
        alpha_deg: float,
        side: int,
        mu: float,
        yaw_rad: float,
        edge: int,
        hook: bool,
        contact_offset: float = 0.0,
    ):
        a = math.radians(alpha_deg)
        # each contact acts this far further in along its inward normal than the point the
        # geometry tracks (a round tip's radius, with ``geom`` the outline grown by it)
        self.reach = float(contact_offset)
        self.edge, self.hook_notch = edge, hook  # the hull edge that left the face; turn in a notch
        self.concave = False  # the corner stopped at a concave vertex (not by circling the outline)
        self.t = np.array([-side * math.sin(a), math.cos(a)])
        self.nf = np.array([-side * math.cos(a), -math.sin(a)])
        self.geom, self.mu, self.yaw = geom, mu, yaw_rad
        self.c2 = geom.limit_radius**2
        self.poly = geom.outline
        self.n = len(self.poly)
        self.step = geom.circumradius / EXIT_STEPS_PER_RADIUS
        self.tol = EXIT_CONTACT_TOL * geom.circumradius
        self.steps_left = int(EXIT_MAX_TRAVEL_RADII * EXIT_STEPS_PER_RADIUS)
        self.hand = float(self.t[0] * self.nf[1] - self.t[1] * self.nf[0])  # (t, nf) handedness
        self.X = np.zeros(2)
        self.phases = ""
        # vertices that have passed the tip: they never land on the face again (where they would
        # meet the fence's end face instead, which the model leaves out)
        self.passed = np.zeros(self.n, dtype=bool)

    def rot(self, yaw=None) -> np.ndarray:
        y = self.yaw if yaw is None else yaw
        c, s = math.cos(y), math.sin(y)
        return np.array([[c, -s], [s, c]])

    def world(self, X=None, yaw=None) -> np.ndarray:
        return (self.X if X is None else X) + self.poly @ self.rot(yaw).T

    def landed(self, pts: np.ndarray, *skip: int) -> np.ndarray:
        """Vertices (not yet past the tip) that have crossed the face upstream of the tip."""
        q = pts @ self.t
        self.passed |= q > self.tol
        hit = (pts @ self.nf < -self.tol) & (q < -self.tol) & ~self.passed
        hit[list(skip)] = False
        return hit

    def caught(self, pts: np.ndarray) -> bool:
        """Whether a vertex past the tip has come back behind it below the face line: it would
        meet the fence's end face, which the model leaves out (the part is let go there)."""
        return bool(np.any(self.passed & (pts @ self.t < -self.tol) & (pts @ self.nf < -self.tol)))

    # -- phases -------------------------------------------------------------------------------
    def flush(self):
        """Slide flush on the face until the shifted foot leaves the supported part of the face;
        returns the next phase ``("C", edge, s)`` or ``("F", vertex)``."""
        pts = self.world()
        on = np.flatnonzero(np.abs(pts @ self.nf) <= self.tol)
        on = on[np.argsort(pts[on] @ self.t)]
        q_all = pts @ self.t
        self.passed |= q_all > self.tol
        sup = [int(k) for k in on if not self.passed[k]]  # on the face, upstream of the tip
        if not sup:
            return ("free", "released")
        q = [float(q_all[k]) for k in sup]
        last = sup[-1]
        crossing = [int(k) for k in on if self.passed[k] and self.adjacent(last, int(k))]
        qf = float(self.X @ self.t) + self.mu * (float(self.X @ self.nf) - self.reach)  # foot shifted mu·d downstream
        if qf <= q[0] and len(sup) > 1:
            return ("F", sup[0])
        if crossing and qf >= q[-1]:  # the edge through the tip carries the foot: the corner takes over
            self.X = self.X + max(0.0, -qf) * self.t
            return self.on_edge(last, crossing[0])
        if qf >= q[-1]:
            return ("F", last)
        i = int(np.searchsorted(q, qf)) - 1
        if self.adjacent(sup[i], sup[i + 1]):  # a face segment: slide until the tip reaches the foot
            self.X = self.X + max(0.0, -qf) * self.t
            return self.on_edge(sup[i], sup[i + 1])
        # a gap: pivot once the vertex past it has left the face (by a margin past the tip)
        self.X = self.X + (max(0.0, -q[i + 1]) + EXIT_PASS_MARGIN * self.geom.circumradius) * self.t
        return ("F", sup[i])

    def adjacent(self, a: int, b: int) -> bool:
        return (a + 1) % self.n == b or (b + 1) % self.n == a

    def on_edge(self, a: int, b: int):
        """``("C", k, s)``: the corner (origin) on the outline edge joining vertices a and b."""
        k = a if (a + 1) % self.n == b else b
        e = self.poly[(k + 1) % self.n] - self.poly[k]
        rel = -(self.X + self.rot() @ self.poly[k])  # the corner relative to vertex k, world
        return ("C", k, float(rel @ (self.rot() @ e)) / float(np.hypot(*e)))

    def pivot(self, v: int):
        """Vertex ``v`` on the face pivots until it passes the tip (free) or another vertex lands
        on the face (flush again)."""
        self.phases += "F"
        nf, t, P = self.nf, self.t, self.poly
        for _ in range(self.steps_left):
            self.steps_left -= 1

            def deriv(X, yaw, v=v):
                r = self.rot(yaw) @ P[v] + self.reach * nf  # where the face's force acts
                tw = _contact_twist(r[0], r[1], nf[0], nf[1], t[0], t[1], self.mu, self.c2)
                return None if tw is None else (np.array([tw[0], tw[1]]) - _PUSHER_VELOCITY, tw[2])

            k1 = deriv(self.X, self.yaw)
            if k1 is None:
                return ("free", "released")
            k2 = deriv(self.X + 0.5 * self.step * k1[0], self.yaw + 0.5 * self.step * k1[1])
            if k2 is None:
                return ("free", "released")
            self.yaw += self.step * k2[1]
            self.X = self.X + self.step * k2[0]
            pv = self.X + self.rot() @ P[v]
            self.X = self.X - float(pv @ nf) * nf  # keep the vertex on the face
            pv = self.X + self.rot() @ P[v]
            if float(pv @ t) >= 0.0:  # past the tip: the corner meets the edge upstream of v
                if self.hand > 0:  # CCW order runs downstream along the face
                    k = (v - 1) % self.n
                    return ("C", k, float(np.hypot(*(P[v] - P[k]))))
                return ("C", v, 0.0)
            corner = self.rot().T @ -self.X  # the tip corner in the part frame
            if _inside(P, corner):  # the corner now holds an outline edge too
                k, sk, gap = self.nearest_edge(corner)
                if gap > self.tol:
                    return ("B", v, k, sk)
            pts = self.world()
            depth = pts @ nf
            hit = self.landed(pts, v)
            if self.caught(pts):
                return ("free", "end face")
            if hit.any():  # turn back about v until the deepest vertex lies on the face
                k = int(np.argmin(np.where(hit, depth, np.inf)))
                w = pts[k] - pv
                ang = math.atan2(float(w @ nf), float(w @ t))  # in the (t, nf) basis
                delta = -ang if float(w @ t) > 0.0 else (math.pi - ang + math.pi) % (2 * math.pi) - math.pi
                self.yaw += self.hand * delta
                self.X = pv - self.rot() @ P[v]
                qk = float((self.X + self.rot() @ P[k]) @ t)
                qf = float(self.X @ t) + self.mu * (float(self.X @ nf) - self.reach)
                if self.adjacent(v, k) and qk > float(pv @ t) and qf > qk:
                    v = k  # rolling on a polygonal curve: the foot is past the new vertex too
                    continue
                return ("flush",)
        return ("free", "travel")

    def corner(self, k: int, s: float):
        """The corner pushes outline edge ``k`` at ``s`` (metres from vertex ``k``) until it
        leaves the outline, stops pushing or meets a concave vertex."""
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
                f = r + self.reach * np.array([-ew[1], ew[0]])  # where the corner's force acts
                tw = _contact_twist(f[0], f[1], -ew[1], ew[0], ew[0], ew[1], self.mu, self.c2)
                if tw is None:
                    return None
                vx, vy, w = tw
                rel = np.array(_PUSHER_VELOCITY) - np.array([vx - w * r[1], vy + w * r[0]])
                return w, float(rel @ ew)

            while self.steps_left > 0:
                self.steps_left -= 1
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
                if hit.any():  # an upstream vertex meets the face: both contacts hold
                    return ("B", int(np.argmin(np.where(hit, pts @ self.nf, np.inf))), k, s)
            else:
                return self.release(k, s, "travel")
            switches += 1
            j = (k + 1) % n if s > length else k  # the vertex reached
            if not self.geom.convex[j] or switches > 2 * n:  # a concave vertex, or the corner circling
                self.concave = not self.geom.convex[j]
                return self.release(k, min(max(s, 0.0), length), "notch")
            k, s = (j, 0.0) if s > length else ((k - 1) % n, float(np.hypot(*(P[k] - P[(k - 1) % n]))))

    def nearest_edge(self, p: np.ndarray) -> tuple[int, float, float]:
        """The outline edge nearest to part-frame point ``p``, the position of its foot along it
        and its distance."""
        a, b = self.poly, np.roll(self.poly, -1, axis=0)
        e = b - a
        length = np.hypot(e[:, 0], e[:, 1])
        s = np.clip(np.sum((p - a) * e, axis=1) / length, 0.0, length)
        foot = a + (s / length)[:, None] * e
        dist = np.hypot(*(foot - p).T)
        k = int(np.argmin(dist))
        return k, float(s[k]), float(dist[k])

    def both(self, v: int, k: int, s: float):
        """Vertex ``v`` slides on the face while the corner holds outline edge ``k`` (at ``s``),
        until one of them lets go."""
        self.phases += "B"
        P, n, nf, t, vp = self.poly, self.n, self.nf, self.t, np.array(_PUSHER_VELOCITY)
        edge = P[(k + 1) % n] - P[k]
        if (
            float(np.hypot(*(P[k] + s * edge / float(np.hypot(*edge)) - P[v])))
            <= EXIT_HOOK_TOL * self.geom.circumradius
        ):
            return self.hooked()
        switches = 0

        def twist(yaw, s, a, e):
            R = self.rot(yaw)
            ew = R @ e
            en = np.array([-ew[1], ew[0]])
            rv, rc = R @ P[v], R @ (a + s * e)
            fv, fc = rv + self.reach * nf, rc + self.reach * en  # where the forces act
            return _two_contact_twist(fv, nf, t, fc, en, ew, self.mu, self.c2), rv, rc, en, ew

        def onto(X, yaw, a, e):
            """X moved back onto both constraints (v on the face, the corner on edge k's line)
            and the corner's position along the edge."""
            R = self.rot(yaw)
            ew = R @ e
            en = np.array([-ew[1], ew[0]])
            dv = float((X + R @ P[v]) @ nf)
            dc = float(-(X + R @ a) @ en)
            X = X + np.linalg.solve(np.array([nf, en]), np.array([-dv, dc]))
            return X, float(-(X + R @ a) @ ew)

        while self.steps_left > 0:
            self.steps_left -= 1
            a = P[k]
            e = P[(k + 1) % n] - a
            length = float(np.hypot(*e))
            e = e / length
            tw, rv, rc, en, ew = twist(self.yaw, s, a, e)
            if tw is None:  # one lets go: the one whose motion alone leaves the other free
                fc = rc + self.reach * en
                tc = _contact_twist(fc[0], fc[1], en[0], en[1], ew[0], ew[1], self.mu, self.c2)
                if tc is not None:
                    vel = np.array([tc[0] - tc[2] * rv[1], tc[1] + tc[2] * rv[0]])
                    if float((vel - vp) @ nf) >= 0.0:
                        return ("C", k, s)
                fv = rv + self.reach * nf
                tf = _contact_twist(fv[0], fv[1], nf[0], nf[1], t[0], t[1], self.mu, self.c2)
                if tf is not None:
                    vel = np.array([tf[0] - tf[2] * rc[1], tf[1] + tf[2] * rc[0]])
                    if float((vel - vp) @ en) >= 0.0:
                        return ("F", v)
                return ("free", "wedged")
            if math.hypot(tw[0] - vp[0], tw[1] - vp[1]) + abs(tw[2]) * self.geom.circumradius <= EXIT_CONTACT_TOL:
                return ("free", "wedged")  # the part moves with the fence: held at the tip
            half = 0.5 * self.step
            xh, sh = onto(self.X + half * (np.array(tw[:2]) - vp), self.yaw + half * tw[2], a, e)
            tw2 = twist(self.yaw + half * tw[2], sh, a, e)[0] or tw  # midpoint rule
            self.yaw += self.step * tw2[2]
            self.X, s = onto(self.X + self.step * (np.array(tw2[:2]) - vp), self.yaw, a, e)
            R = self.rot()
            if float((self.X + R @ P[v]) @ t) >= 0.0:  # v passed the tip: the corner alone
                return ("C", k, min(max(s, 0.0), length))
            if not 0.0 <= s <= length:
                switches += 1
                j = (k + 1) % n if s > length else k
                if not self.geom.convex[j] or switches > 2 * n:
                    self.concave = not self.geom.convex[j]
                    return self.release(k, min(max(s, 0.0), length), "notch")
                k, s = (j, 0.0) if s > length else ((k - 1) % n, float(np.hypot(*(P[k] - P[(k - 1) % n]))))
                continue
            pts = self.world()
            hit = self.landed(pts, v)
            if self.caught(pts):
                return ("free", "end face")
            if hit.any():
                w = int(np.argmin(np.where(hit, pts @ nf, np.inf)))
                if not self.adjacent(v, w):
                    return ("flush",)
                # rolling on a polygonal curve: turn about the corner until w lies on the face
                ang = math.atan2(float(pts[w] @ nf), float(pts[w] @ t))
                self.yaw += self.hand * ((math.pi - ang + math.pi) % (2 * math.pi) - math.pi)
                self.X = -(self.rot() @ (a + s * e))
                v = w
        return ("free", "travel")

    def hooked(self):
        """A vertex caught on the tip corner (both contacts at one point): the part would swing
        about the corner, which the model does not follow; it is let go as it is (a known miss:
        a C shape open towards the fence turns by about −50° in the simulator, not 0°)."""
        self.phases += "H"
        return ("free", "hooked")

    def release(self, k, s, reason):
        """Let the corner go at edge ``k``, position ``s``; the part then rides the belt (the
        corner moves at ``_PUSHER_VELOCITY`` relative to it) and the corner meets it again if
        that ray hits the outline (a concave part hooking the tip: e.g. a C open to the fence)."""
        a = self.poly[k]
        e = self.poly[(k + 1) % self.n] - a
        p = a + s * e / float(np.hypot(*e))
        self.X = -(self.rot() @ p)  # the corner is at the contact point
        if reason == "notch" and self.hook_notch and self.concave:
            return self.hook()
        if reason != "released":
            return ("free", reason)
        d = self.rot().T @ np.array(_PUSHER_VELOCITY)  # the corner's path in the part frame
        hit = self.ray(p, d)
        if hit is None:
            return ("free", reason)
        j, sj, dist = hit
        self.X = self.X - dist * np.array(_PUSHER_VELOCITY)
        return ("C", j, sj)

    def hook(self):
        """The corner caught in a notch (at the contact, ``X`` already there): the part turns about
        it by the smallest angle that lays the hull edge it rode the face on along the travel
        direction, and is let go (docs/structured.md, "A candidate for the notch": the "flush"
        rule). An empirical rule, adopted on its scores against the simulator: it does not check
        whether the corner's further path meets the part again, and it often does."""
        self.phases += "N"
        hull = self.geom.hull
        e = self.rot() @ (hull[(self.edge + 1) % len(hull)] - hull[self.edge])
        travel = math.atan2(_PUSHER_VELOCITY[1], _PUSHER_VELOCITY[0])
        # either way along the travel line: the smaller turn, in [-90°, 90°)
        turn = (travel - math.atan2(float(e[1]), float(e[0])) + math.pi / 2) % math.pi - math.pi / 2
        c, s = math.cos(turn), math.sin(turn)
        self.yaw += turn
        self.X = np.array([[c, -s], [s, c]]) @ self.X  # about the corner (the origin)
        return ("free", "notch")

    def ray(self, p: np.ndarray, d: np.ndarray):
        """First outline edge hit by the ray ``p + λ d`` (part frame, λ beyond a small margin):
        ``(edge, position along it, λ)`` or None."""
        a, b = self.poly, np.roll(self.poly, -1, axis=0)
        e = b - a
        den = d[0] * e[:, 1] - d[1] * e[:, 0]
        w = a - p
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = (w[:, 0] * e[:, 1] - w[:, 1] * e[:, 0]) / den
            u = (w[:, 0] * d[1] - w[:, 1] * d[0]) / den
        ok = (den != 0.0) & (u >= 0.0) & (u <= 1.0) & (lam > EXIT_PASS_MARGIN * self.geom.circumradius)
        if not ok.any():
            return None
        j = int(np.argmin(np.where(ok, lam, np.inf)))
        return j, float(u[j] * np.hypot(*e[j])), float(lam[j])


def exit_turn(
    part, edge: int, fence_angle_deg: float, side: int, mu: float, hook: bool = False, contact_offset: float = 0.0
) -> ExitTurn:
    """The turn of a part leaving the tip of a fence (local angle ``fence_angle_deg``) resting
    flush on hull edge ``edge`` (a stable edge of :func:`push_function` with the same ``mu`` and
    ``side``). Quasi-static phases, with the actual outline: the part slides flush until the foot
    shifted ``mu·d`` downstream leaves the supported part of the face; then either the tip corner
    pushes an outline edge (``C``: the edge turns about the corner towards the travel direction
    until the corner slides off its end) or, where the hull edge bridges a concavity, the last
    supported vertex pivots on the face (``F``) until it passes the tip or another vertex lands
    on the face (flush again). ``hook``: where the corner reaches a notch, turn the part about it
    until hull edge ``edge`` lies along the travel direction (:meth:`_Exit.hook`; the model of a
    round tip), instead of letting it go as it is. ``contact_offset``: with ``part`` an outline grown
    by a round tip's radius (:func:`feeder.mechanics.hull.dilate`), that radius: every contact force
    then acts that far further in along its normal, on the part itself (the grown outline only
    places the contacts), for its moment and its slip; 0: where the grown outline touches."""
    geom = as_geometry(part)
    if not (math.isfinite(contact_offset) and contact_offset >= 0.0):
        raise FeederError(f"contact_offset must be finite and >= 0, got {contact_offset!r}")
    yaw0 = math.radians(float(resting_yaw(geom.normals_deg[edge], fence_angle_deg, side)))
    ex = _Exit(geom, fence_angle_deg, side, mu, yaw0, int(edge), bool(hook), float(contact_offset))
    a = geom.hull[edge]
    along = ex.rot() @ (geom.hull[(edge + 1) % len(geom.hull)] - a)
    ex.X = -(ex.rot() @ a)  # hull edge on the face line, first vertex at the tip ...
    ex.X = ex.X - max(0.0, float(along @ ex.t)) * ex.t  # ... and its downstream end there
    state = _follow(ex, ("flush",))
    reason = state[1] if state[0] == "free" else "phases"
    return ExitTurn(math.degrees(ex.yaw - yaw0), (float(ex.X[0]), float(ex.X[1])), reason, ex.phases)


def corner_push(part, fence_angle_deg: float, side: int, mu: float, yaw_deg: float, lateral: float):
    """A part riding the belt at yaw ``yaw_deg``, its centroid ``lateral`` metres (world x) from a
    fence's tip corner, meets that corner head on (a curved fence whose tip reaches into the lane:
    the part grazes it instead of meeting the face). The corner pushes the outline where it first
    meets it, with the exit turn's phases from there (``C`` first; the face at local angle
    ``fence_angle_deg`` if a vertex lands on it). Returns the :class:`ExitTurn` (``delta_deg``
    from ``yaw_deg``, ``offset`` the centroid from the corner when let go), or None if the
    corner's path misses the outline."""
    geom = as_geometry(part)
    yaw0 = math.radians(float(yaw_deg))
    ex = _Exit(geom, fence_angle_deg, side, mu, yaw0, 0, False)
    ex.X = np.array([float(lateral), -2.0 * geom.circumradius])  # the whole part upstream of the corner
    hit = ex.ray(ex.rot().T @ -ex.X, ex.rot().T @ np.array(_PUSHER_VELOCITY))
    if hit is None:
        return None
    j, sj, dist = hit
    ex.X = ex.X - dist * np.array(_PUSHER_VELOCITY)
    state = _follow(ex, ("C", j, sj))
    reason = state[1] if state[0] == "free" else "phases"
    return ExitTurn(math.degrees(ex.yaw - yaw0), (float(ex.X[0]), float(ex.X[1])), reason, ex.phases)


def _follow(ex: _Exit, state: tuple) -> tuple:
    """Run the exit state machine from ``state`` until the part is let go (``("free", why)``) or
    the phase limit."""
    seen: set = set()
    for _ in range(EXIT_MAX_PHASES):
        if state[0] == "flush":
            state = ex.flush()
            key = (state, round(ex.yaw / EXIT_SAME_RAD))
            if key in seen:  # back where it was: no progress (a part wedged on the face)
                state = ("free", "stuck")
                break
            seen.add(key)
        elif state[0] == "F":
            state = ex.pivot(state[1])
        elif state[0] == "C":
            state = ex.corner(state[1], state[2])
        elif state[0] == "B":
            state = ex.both(state[1], state[2], state[3])
        else:
            break
    return state
