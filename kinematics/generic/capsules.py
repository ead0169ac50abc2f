"""Compiled closed-form signed distances between capsules, spheres and plates, batched over
configurations on every core; coal (through `CollisionModel`) for every other pair.

Shapes with closed forms (all convex; "signed distance" as coal's: the gap when apart, minus the
penetration depth, the shortest translation that separates them, when they overlap):

* **capsule - capsule** (a sphere is a capsule of zero length): the points within r of a segment.
  The Minkowski difference of two capsules is the set within r1 + r2 of the difference of their
  segments, a (flat) parallelogram P, so their signed distance is, everywhere,

      d = |s1(u*) - s2(v*)| - r1 - r2,   (u*, v*) = argmin over [0, 1]^2 of |s1(u) - s2(v)|,

  the segments' distance by the clamped closed form (Ericson, Real-Time Collision Detection 5.1.9;
  parallel segments included);
* **capsule - plate** (a `coal.Cylinder`: centre c, unit axis a, radius R, half thickness h).
  With z_k = a.(p_k - c) the capsule's end heights and rho_k their distances from the axis, the
  slab |a.(x - c)| <= h gives

      d = max(min z_k - r - h, -h - max z_k - r),

  and this is the plate's own signed distance whenever the capsule's footprint stays inside the
  disk, max rho_k + r <= R - max(0, -d): apart, the slab's nearest points are then on the disk's
  faces; overlapping, any translation shorter than -d keeps the footprint inside the disk, so only
  leaving the slab separates them. Elsewhere the pair goes to coal (the base plates of the
  built-ins and the rods above them meet the test; a rod beside a plate does not), or, where only
  the sign matters (`distances(signs=True)`, the workspace margins), keeps a positive lower bound
  when it finds one: the slab's distance, or min(m, rho - R - r) with rho the distance from the
  axis of the segment's part within |z| <= h + r + m (m = h + r; beyond that band the height
  alone keeps the capsule m away).

* **capsule - half-space** (a `coal.Halfspace`, the solid n.x <= d; an obstacle's wall or floor):
  with z_k = n.p_k - d the end heights, d = min z_k - r, exact apart and in penetration (the
  half-space's nearest face is the plane).

Everything else (boxes, cylinders against cylinders, meshes) is coal's. Placements come from the
compiled forward kinematics (`kinematics.generic.batched`) of each geometry's parent frame.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit, prange

from kinematics.chunks import slices
from kinematics.generic.collision import CollisionModel

CAPSULE, PLATE, COAL, HALFSPACE = 0, 1, 2, 3
"""Pair kinds: closed form, closed form where the footprint test holds, coal, closed form."""

CHUNK = 16384
"""Configurations per batch: placements and distances of a chunk stay small."""


class AnalyticDistances:
    """Signed distances of a `CollisionModel`'s pairs, closed-form where the shapes allow
    (module docstring), coal for the rest; `distances(q)` agrees with `CollisionModel.distances`.

    Attributes:
        model: the collision model (pairs, names, coal for the other pairs).
        kinds: (P,) CAPSULE, PLATE, COAL or HALFSPACE per pair.
    """

    def __init__(self, model: CollisionModel) -> None:
        import coal

        from kinematics.generic.batched import BatchedKinematics

        self.model = model
        objs = list(model.geometry.geometryObjects)
        G = len(objs)
        self._radius = np.zeros(G)
        self._half = np.zeros(G)
        shape = np.full(G, COAL, dtype=np.int64)
        # each shape's reference point and direction in its joint's frame: the centre and the z
        # axis, for a half-space a point of its plane (d n) and its normal n
        self._local_p = np.array([objs[k].placement.translation for k in range(G)]).reshape(G, 3)
        self._local_axis = np.array([objs[k].placement.rotation[:, 2] for k in range(G)]).reshape(G, 3)
        for k, g in enumerate(objs):
            geom = g.geometry
            if isinstance(geom, coal.Capsule):
                shape[k], self._radius[k], self._half[k] = CAPSULE, geom.radius, geom.halfLength
            elif isinstance(geom, coal.Sphere):
                shape[k], self._radius[k] = CAPSULE, geom.radius
            elif isinstance(geom, coal.Cylinder):
                shape[k], self._radius[k], self._half[k] = PLATE, geom.radius, geom.halfLength
            elif isinstance(geom, coal.Halfspace):
                shape[k] = HALFSPACE
                rot = g.placement.rotation
                self._local_p[k] = g.placement.translation + rot @ (geom.d * np.asarray(geom.n))
                self._local_axis[k] = rot @ np.asarray(geom.n)
        pairs = np.array(model.pairs, dtype=np.int64).reshape(-1, 2)
        kinds = np.full(len(pairs), COAL, dtype=np.int64)
        for n, (a, b) in enumerate(pairs):
            sa, sb = shape[a], shape[b]
            if sa == CAPSULE and sb == CAPSULE:
                kinds[n] = CAPSULE
            elif {sa, sb} in ({CAPSULE, PLATE}, {CAPSULE, HALFSPACE}):
                kinds[n] = sa if sa != CAPSULE else sb
                if sa != CAPSULE:
                    pairs[n] = (b, a)  # capsule first
        self.kinds = kinds
        self._pairs = pairs
        used = sorted({int(x) for x in pairs[kinds != COAL].ravel()})
        self._used = np.array(used, dtype=np.int64)
        # a geometry's placement is in its parent joint's frame: compile each joint's own frame
        rb = model.robot.model
        self._frame_of = {k: _joint_frame(rb, int(objs[k].parentJoint)) for k in used}
        self._fk = {f: BatchedKinematics.from_model(rb, f, model.robot.name) for f in set(self._frame_of.values())}

    def _placements(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, G, 3) centres and (N, G, 3) z axes of the closed-form geometries in the world."""
        N, G = len(q), len(self._radius)
        centre = np.zeros((N, G, 3))
        axis = np.zeros((N, G, 3))
        poses = {f: fk.fk(q) for f, fk in self._fk.items()}
        for k in self._used:
            pose = poses[self._frame_of[int(k)]]
            centre[:, k] = pose.position + np.einsum("nij,j->ni", pose.rotation, self._local_p[k])
            axis[:, k] = np.einsum("nij,j->ni", pose.rotation, self._local_axis[k])
        return centre, axis

    def closed_form(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, P) closed-form distances [m] and (N, P) where they hold (False: a COAL pair, NaN, or
        a PLATE pair whose footprint test fails, whose entry is then a positive lower bound of its
        distance when one is found (the slab's distance, or the gap beside the disk), else NaN)."""
        q = np.ascontiguousarray(q, dtype=float)
        out = np.empty((len(q), len(self.kinds)))
        ok = np.empty((len(q), len(self.kinds)), dtype=np.bool_)
        for s in slices(len(q), CHUNK):
            centre, axis = self._placements(q[s])
            _kernel(centre, axis, self._radius, self._half, self._pairs, self.kinds, out[s], ok[s])
        return out, ok

    def distances(self, q: np.ndarray, signs: bool = False) -> np.ndarray:
        """(N, P) signed distances [m], pair order as the model's: closed form where it holds,
        coal (`CollisionModel.distances`) for the configurations where some pair needs it.

        signs: where a capsule lies beside a plate and clear of it, keep `closed_form`'s positive
        lower bound instead of asking coal: every entry then has the sign of the true distance
        (and is exact wherever it is <= 0), which is all a margin's zero set needs."""
        q = np.asarray(q, dtype=float)
        if q.ndim != 2 or q.shape[1] != self.model.robot.model.nq or not np.isfinite(q).all():
            return self.model.distances(q)  # raises the model's error
        out, ok = self.closed_form(q)
        if signs:
            ok |= (self.kinds == PLATE) & (out > 0)
        rows = np.flatnonzero(~ok.all(axis=1))
        if len(rows):
            d = self.model.distances(q[rows])
            out[rows] = np.where(ok[rows], out[rows], d)
        return out

    def margin(self, q: np.ndarray, signs: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Smallest signed distance [m] over the pairs and its pair index (-1, +inf: no pair);
        `signs` as in `distances`."""
        d = self.distances(q, signs)
        if d.shape[1] == 0:
            return np.full(len(d), np.inf), np.full(len(d), -1)
        k = np.argmin(d, axis=1)
        return d[np.arange(len(d)), k], k


def _joint_frame(model: Any, joint: int) -> int:
    """The index of joint `joint`'s own frame (placement identity in the joint)."""
    import pinocchio as pin

    return next(f for f, fr in enumerate(model.frames)
                if (fr.parentJoint == joint and fr.type in (pin.FrameType.JOINT, pin.FrameType.FIXED_JOINT)
                and fr.placement.isIdentity()) or (joint == 0 and f == 0))


@njit(cache=True, inline="always")
def _segments(p1x, p1y, p1z, d1x, d1y, d1z, p2x, p2y, p2z, d2x, d2y, d2z):  # pragma: no cover - compiled
    """Distance [m] between segments p1 + s d1 and p2 + t d2, s, t in [0, 1] (Ericson 5.1.9,
    clamped; parallel and degenerate segments included)."""
    rx, ry, rz = p1x - p2x, p1y - p2y, p1z - p2z
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    eps = 1e-300
    s = 0.0
    t = 0.0
    if a <= eps and e <= eps:
        pass
    elif a <= eps:
        t = min(max(f / e, 0.0), 1.0)
    else:
        c = d1x * rx + d1y * ry + d1z * rz
        if e <= eps:
            s = min(max(-c / a, 0.0), 1.0)
        else:
            b = d1x * d2x + d1y * d2y + d1z * d2z
            denom = a * e - b * b
            if denom > 0.0:
                s = min(max((b * f - c * e) / denom, 0.0), 1.0)
            t = (b * s + f) / e
            if t < 0.0:
                t = 0.0
                s = min(max(-c / a, 0.0), 1.0)
            elif t > 1.0:
                t = 1.0
                s = min(max((b - c) / a, 0.0), 1.0)
    x = rx + d1x * s - d2x * t
    y = ry + d1y * s - d2y * t
    z = rz + d1z * s - d2z * t
    return math.sqrt(x * x + y * y + z * z)


@njit(cache=True, parallel=True)
def _kernel(centre, axis, radius, half, pairs, kinds, out, ok):  # pragma: no cover - compiled
    N = centre.shape[0]
    P = pairs.shape[0]
    for n in prange(N):
        for k in range(P):
            i = pairs[k, 0]
            j = pairs[k, 1]
            kind = kinds[k]
            if kind == 2:
                out[n, k] = np.nan
                ok[n, k] = False
                continue
            hi = half[i]
            ax, ay, az = axis[n, i, 0], axis[n, i, 1], axis[n, i, 2]
            p1x = centre[n, i, 0] - hi * ax
            p1y = centre[n, i, 1] - hi * ay
            p1z = centre[n, i, 2] - hi * az
            if kind == 0:
                hj = half[j]
                bx, by, bz = axis[n, j, 0], axis[n, j, 1], axis[n, j, 2]
                dist = _segments(p1x, p1y, p1z, 2 * hi * ax, 2 * hi * ay, 2 * hi * az,
                                 centre[n, j, 0] - hj * bx, centre[n, j, 1] - hj * by, centre[n, j, 2] - hj * bz,
                                 2 * hj * bx, 2 * hj * by, 2 * hj * bz)
                out[n, k] = dist - radius[i] - radius[j]
                ok[n, k] = True
                continue
            if kind == 3:  # capsule i against the half-space j: n.x <= n.c
                zu = axis[n, j, 0] * (p1x - centre[n, j, 0]) + axis[n, j, 1] * (p1y - centre[n, j, 1]) \
                    + axis[n, j, 2] * (p1z - centre[n, j, 2])
                zv = zu + 2 * hi * (axis[n, j, 0] * ax + axis[n, j, 1] * ay + axis[n, j, 2] * az)
                out[n, k] = min(zu, zv) - radius[i]
                ok[n, k] = True
                continue
            # capsule i against plate j (axis a, centre c): end heights z and axis distances rho
            cx, cy, cz = centre[n, j, 0], centre[n, j, 1], centre[n, j, 2]
            a0, a1, a2 = axis[n, j, 0], axis[n, j, 1], axis[n, j, 2]
            ux, uy, uz = p1x - cx, p1y - cy, p1z - cz
            vx, vy, vz = ux + 2 * hi * ax, uy + 2 * hi * ay, uz + 2 * hi * az
            zu = a0 * ux + a1 * uy + a2 * uz
            zv = a0 * vx + a1 * vy + a2 * vz
            wx, wy, wz = ux - zu * a0, uy - zu * a1, uz - zu * a2
            ru = math.sqrt(wx * wx + wy * wy + wz * wz)
            wx, wy, wz = vx - zv * a0, vy - zv * a1, vz - zv * a2
            rv = math.sqrt(wx * wx + wy * wy + wz * wz)
            r = radius[i]
            h = half[j]
            d = max(min(zu, zv) - r - h, -h - max(zu, zv) - r)
            ok[n, k] = max(ru, rv) + r <= radius[j] - max(0.0, -d)
            if ok[n, k] or d > 0.0:
                out[n, k] = d  # exact, or a lower bound: the disk is in the slab
                continue
            # beside the disk: on the axis part within the band |z| <= h + r + m (m = h + r > 0) the
            # segment's distance to the axis, less R + r, bounds the gap; beyond the band the
            # height alone keeps the segment m + r away: min(m, that) when positive, else NaN
            m = h + r
            band = h + r + m
            s0, s1 = 0.0, 1.0
            if zv != zu:
                sa = (-band - zu) / (zv - zu)
                sb = (band - zu) / (zv - zu)
                s0 = max(0.0, min(sa, sb))
                s1 = min(1.0, max(sa, sb))
            gap = m
            if s0 <= s1:
                e0x, e0y, e0z = p1x + 2 * hi * ax * s0, p1y + 2 * hi * ay * s0, p1z + 2 * hi * az * s0
                rho = _segments(e0x, e0y, e0z, 2 * hi * ax * (s1 - s0), 2 * hi * ay * (s1 - s0), 2 * hi * az * (s1 - s0),
                                cx - band * a0, cy - band * a1, cz - band * a2, 2 * band * a0, 2 * band * a1, 2 * band * a2)
                gap = min(m, rho - radius[j] - r)
            out[n, k] = gap if gap > 0.0 else np.nan


def kernels() -> tuple[Any, ...]:
    """The compiled kernels (for `kinematics.jit`)."""
    return (_kernel,)
