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

Everything else (boxes, cylinders against cylinders, meshes) is coal's. Placements come from one
compiled pass over the tree of the geometries' joints (`_tree_kernel`; joint data as
`kinematics.generic.batched` reads them).
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

PARALLEL_MIN = 2048
"""Smaller batches run on one core: a parallel launch costs more than they do (milliseconds on a
loaded machine; the column engine's root refinement calls with a few hundred points)."""


class AnalyticDistances:
    """Signed distances of a `CollisionModel`'s pairs, closed-form where the shapes allow
    (module docstring), coal for the rest; `distances(q)` agrees with `CollisionModel.distances`.

    Attributes:
        model: the collision model (pairs, names, coal for the other pairs).
        kinds: (P,) CAPSULE, PLATE, COAL or HALFSPACE per pair.
    """

    def __init__(self, model: CollisionModel) -> None:
        import coal

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
        self._tree = _Tree(model.robot.model, [int(objs[k].parentJoint) for k in used], model.robot.name)

    def _placements(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, G, 3) centres and (N, G, 3) z axes of the closed-form geometries in the world (one
        compiled pass over the tree of their joints, `_tree_kernel`)."""
        N, G = len(q), len(self._radius)
        centre = np.zeros((N, G, 3))
        axis = np.zeros((N, G, 3))
        if len(self._used):
            t = self._tree
            (_tree_kernel if N >= PARALLEL_MIN else _tree_serial)(np.ascontiguousarray(q), t.parent, t.kind, t.axis, t.idx_q, t.rotation, t.translation,
                         t.of_geometry, self._used, self._local_p, self._local_axis, centre, axis)
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
            (_kernel if len(centre) >= PARALLEL_MIN else _kernel_serial)(
                centre, axis, self._radius, self._half, self._pairs, self.kinds, out[s], ok[s])
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
            d = self.model.distances(q[rows], only=np.flatnonzero(~ok[rows].all(axis=0)))
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


class _Tree:
    """The joints on the way from the root to the given joints (parents before children), compiled
    for `_tree_kernel`: each one's parent (index in this list, -1 for the world), kind
    (`batched.REVOLUTE`, `CONTINUOUS` or `PRISMATIC`), unit axis, first index in q and placement
    in its parent; `of_geometry[k]` the list index of the k-th given joint (-1: the world)."""

    def __init__(self, model: Any, joints: list[int], name: str) -> None:
        from kinematics.generic.batched import BatchedKinematics

        chains: dict[int, tuple[int, ...]] = {}
        for leaf in set(joints):
            chain, j = [], leaf
            while j > 0:
                chain.append(j)
                j = int(model.parents[j])
            chains[leaf] = tuple(reversed(chain))
        ids = sorted({j for c in chains.values() for j in c})
        at = {j: n for n, j in enumerate(ids)}
        n = len(ids)
        self.parent = np.array([at.get(int(model.parents[j]), -1) for j in ids], dtype=np.int64)
        self.kind = np.zeros(n, dtype=np.int64)
        self.axis = np.zeros((n, 3))
        self.idx_q = np.zeros(n, dtype=np.int64)
        self.rotation = np.zeros((n, 3, 3))
        self.translation = np.zeros((n, 3))
        for leaf, links in chains.items():
            if not links:
                continue
            # the chain's joint data as the batched kinematics read it (kinds, axes from the
            # motion subspace, placements), from the leaf joint's own frame
            bk = BatchedKinematics.from_model(model, _joint_frame(model, leaf), name)
            for k, j in enumerate(links):
                m = at[j]
                self.kind[m], self.axis[m], self.idx_q[m] = bk.kind[k], bk.axis[k], bk.idx_q[k]
                self.rotation[m], self.translation[m] = bk.rotation[k], bk.translation[k]
        self.of_geometry = np.array([at.get(j, -1) for j in joints], dtype=np.int64)


def _joint_frame(model: Any, joint: int) -> int:
    """The index of joint `joint`'s own frame (placement identity in the joint)."""
    import pinocchio as pin

    return next(f for f, fr in enumerate(model.frames)
                if (fr.parentJoint == joint and fr.type in (pin.FrameType.JOINT, pin.FrameType.FIXED_JOINT)
                and fr.placement.isIdentity()) or (joint == 0 and f == 0))


@njit(cache=True, parallel=True)
def _tree_kernel(q, parent, kind, axis, iq, rot, tra, of_geometry, used, local_p, local_axis, centre, out_axis
                 ):  # pragma: no cover - compiled
    """World placements of every joint of the tree (parents first), oM_j = oM_parent M_j X_j(q)
    with X_j a rotation by t about the axis a (Rodrigues, as Pinocchio; (cos t, sin t) from q for
    a continuous joint) or a translation t a; then each used geometry's centre oR_j p + op_j and
    axis oR_j a_local, in blocks of 64 configurations on every core."""
    J = parent.shape[0]
    for blk in prange((q.shape[0] + 63) // 64):
        R = np.empty((J, 3, 3))
        p = np.empty((J, 3))
        for n in range(blk * 64, min(q.shape[0], blk * 64 + 64)):
            _tree_row(q, n, parent, kind, axis, iq, rot, tra, of_geometry, used, local_p, local_axis, centre, out_axis,
                      R, p)


@njit(cache=True)
def _tree_serial(q, parent, kind, axis, iq, rot, tra, of_geometry, used, local_p, local_axis, centre, out_axis
                 ):  # pragma: no cover - compiled
    """`_tree_kernel` on one core (small batches: no parallel launch)."""
    J = parent.shape[0]
    R = np.empty((J, 3, 3))
    p = np.empty((J, 3))
    for n in range(q.shape[0]):
        _tree_row(q, n, parent, kind, axis, iq, rot, tra, of_geometry, used, local_p, local_axis, centre, out_axis, R, p)


@njit(cache=True, inline="always")
def _tree_row(q, n, parent, kind, axis, iq, rot, tra, of_geometry, used, local_p, local_axis, centre, out_axis, R, p
              ):  # pragma: no cover - compiled
    """`_tree_kernel` at configuration n, with scratch R (J, 3, 3) and p (J, 3)."""
    for j in range(parent.shape[0]):
        _joint_pose(q, n, j, parent[j], kind[j], axis, iq[j], rot, tra, R, p)
    for m in range(used.shape[0]):
        g, j = used[m], of_geometry[m]
        for r in range(3):
            if j < 0:
                centre[n, g, r], out_axis[n, g, r] = local_p[g, r], local_axis[g, r]
            else:
                centre[n, g, r] = p[j, r] + R[j, r, 0] * local_p[g, 0] + R[j, r, 1] * local_p[g, 1] \
                    + R[j, r, 2] * local_p[g, 2]
                out_axis[n, g, r] = R[j, r, 0] * local_axis[g, 0] + R[j, r, 1] * local_axis[g, 1] \
                    + R[j, r, 2] * local_axis[g, 2]


@njit(cache=True, inline="always")
def _joint_pose(q, n, j, u, kind, axis, iq, rot, tra, R, p):  # pragma: no cover - compiled
    """Joint j's world rotation R[j] and origin p[j] at configuration q[n], from its parent u's."""
    for r in range(3):
        if u < 0:
            for c in range(3):
                R[j, r, c] = rot[j, r, c]
            p[j, r] = tra[j, r]
        else:
            for c in range(3):
                R[j, r, c] = R[u, r, 0] * rot[j, 0, c] + R[u, r, 1] * rot[j, 1, c] + R[u, r, 2] * rot[j, 2, c]
            p[j, r] = p[u, r] + R[u, r, 0] * tra[j, 0] + R[u, r, 1] * tra[j, 1] + R[u, r, 2] * tra[j, 2]
    ax, ay, az = axis[j, 0], axis[j, 1], axis[j, 2]
    t = q[n, iq]
    if kind == 2:  # prismatic: p += t R a
        for r in range(3):
            p[j, r] += t * (R[j, r, 0] * ax + R[j, r, 1] * ay + R[j, r, 2] * az)
        return
    if kind == 1:  # continuous: (cos t, sin t) from q
        cs, sn = t, q[n, iq + 1]
    else:
        cs, sn = math.cos(t), math.sin(t)
    d = 1.0 - cs
    e00, e01, e02 = cs + d * ax * ax, d * ax * ay - sn * az, d * ax * az + sn * ay
    e10, e11, e12 = d * ay * ax + sn * az, cs + d * ay * ay, d * ay * az - sn * ax
    e20, e21, e22 = d * az * ax - sn * ay, d * az * ay + sn * ax, cs + d * az * az
    for r in range(3):
        a0, a1, a2 = R[j, r, 0], R[j, r, 1], R[j, r, 2]
        R[j, r, 0] = a0 * e00 + a1 * e10 + a2 * e20
        R[j, r, 1] = a0 * e01 + a1 * e11 + a2 * e21
        R[j, r, 2] = a0 * e02 + a1 * e12 + a2 * e22


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
    for n in prange(centre.shape[0]):
        _pairs_row(n, centre, axis, radius, half, pairs, kinds, out, ok)


@njit(cache=True)
def _kernel_serial(centre, axis, radius, half, pairs, kinds, out, ok):  # pragma: no cover - compiled
    """`_kernel` on one core (small batches: no parallel launch)."""
    for n in range(centre.shape[0]):
        _pairs_row(n, centre, axis, radius, half, pairs, kinds, out, ok)


@njit(cache=True, inline="always")
def _pairs_row(n, centre, axis, radius, half, pairs, kinds, out, ok):  # pragma: no cover - compiled
    """Every pair's closed form at configuration n."""
    for k in range(pairs.shape[0]):
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
    return (_kernel, _kernel_serial, _tree_kernel, _tree_serial)
