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

Everything else (boxes, cylinders against cylinders, meshes) is coal's; where only signs matter,
a pair of those whose bounding capsules are apart is not (`kinematics.generic.bounding`). Each configuration's
placements (a pass over the tree of the geometries' joints; joint data as
`kinematics.generic.batched` reads them) and pair distances come from one compiled pass
(`capsule_kernels.closed_form_kernel`), on every core, or on one thread for a small batch
(`PARALLEL_MIN`, `jit.on_cores`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from kinematics.chunks import slices
from kinematics.generic import capsule_kernels
from kinematics.generic.bounding import bound_model
from kinematics.generic.capsule_kernels import closed_form_kernel, pair_rows_kernel, pairs_kernel, tree_kernel
from kinematics.generic.collision import CollisionModel
from kinematics.jit import on_cores

CAPSULE, PLATE, COAL, HALFSPACE = 0, 1, 2, 3
"""Pair kinds: closed form, closed form where the footprint test holds, coal, closed form."""

CHUNK = 16384
"""Configurations per batch: placements and distances of a chunk stay small."""

PARALLEL_MIN = 2048
"""Smaller batches run on one core (`jit.on_cores`): a parallel launch costs more than they do
(milliseconds on a loaded machine; the column engine's root refinement calls with a few hundred
points)."""


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
        self._joint_of = np.full(G, -1, dtype=np.int64)  # each closed-form shape's tree joint (-1: the world)
        self._joint_of[self._used] = self._tree.of_geometry
        # the coal pairs' bounding capsules (`kinematics.generic.bounding`): their closed forms
        # prove most of those pairs apart where only signs matter
        bounds = bound_model(model, np.flatnonzero(kinds == COAL)) if (kinds == COAL).any() else None
        self._bound = AnalyticDistances(bounds) if bounds is not None else None  # type: ignore[arg-type]
        self._bound_of = bounds.of if bounds is not None else np.zeros(0, dtype=np.int64)

    def _placements(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, G, 3) centres and (N, G, 3) z axes of the closed-form geometries in the world (one
        compiled pass over the tree of their joints, `capsule_kernels.tree_kernel`)."""
        N, G = len(q), len(self._radius)
        centre = np.zeros((N, G, 3))
        axis = np.zeros((N, G, 3))
        if len(self._used):
            t = self._tree
            on_cores(tree_kernel, N, PARALLEL_MIN, np.ascontiguousarray(q), t.parent, t.kind, t.axis, t.idx_q, t.rotation,
                     t.translation, t.of_geometry, self._used, self._local_p, self._local_axis, centre, axis)
        return centre, axis

    def closed_form(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, P) closed-form distances [m] and (N, P) where they hold (False: a COAL pair, NaN, or
        a PLATE pair whose footprint test fails, whose entry is then a positive lower bound of its
        distance when one is found (the slab's distance, or the gap beside the disk), else NaN)."""
        q = np.ascontiguousarray(q, dtype=float)
        out = np.empty((len(q), len(self.kinds)))
        ok = np.empty((len(q), len(self.kinds)), dtype=np.bool_)
        # the tree posed and the pairs evaluated per configuration in one compiled pass (no
        # (N, G, 3) placements in between)
        on_cores(closed_form_kernel, len(q), PARALLEL_MIN, q, *self.closed_form_data(), out, ok)
        return out, ok

    def closed_form_in_two(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """`closed_form` by its two passes: every placement (`_placements`), then every pair
        (`pairs_kernel`) (the fused pass's reference in the tests)."""
        q = np.ascontiguousarray(q, dtype=float)
        out = np.empty((len(q), len(self.kinds)))
        ok = np.empty((len(q), len(self.kinds)), dtype=np.bool_)
        for s in slices(len(q), CHUNK):
            centre, axis = self._placements(q[s])
            on_cores(pairs_kernel, len(centre), PARALLEL_MIN, centre, axis, self._radius, self._half, self._pairs,
                     self.kinds, out[s], ok[s])
        return out, ok

    def distances(self, q: np.ndarray, signs: bool = False) -> np.ndarray:
        """(N, P) signed distances [m], pair order as the model's: closed form where it holds,
        coal (`CollisionModel.distances`) for the configurations where some pair needs it.

        signs: where a capsule lies beside a plate and clear of it, keep `closed_form`'s positive
        lower bound instead of asking coal, likewise for a coal pair whose bounding capsules
        (`kinematics.generic.bounding`) are apart, and a mesh pair's distance is min(d,
        `collision.NEAR`) (`CollisionModel.distances(near=True)`): every entry then has the sign
        of the true distance (and is exact wherever it is <= 0), which is all a margin's zero set
        needs."""
        q = np.asarray(q, dtype=float)
        if q.ndim != 2 or q.shape[1] != self.model.robot.model.nq or not np.isfinite(q).all():
            return self.model.distances(q)  # raises the model's error
        out, ok = self.closed_form(q)
        if signs:
            ok |= (self.kinds == PLATE) & (out > 0)
            if self._bound is not None:  # coal pairs whose bounding capsules are apart
                bound = self._bound.closed_form(q)[0]
                apart = bound > 0
                cols = self._bound_of
                out[:, cols] = np.where(apart, bound, out[:, cols])
                ok[:, cols] |= apart
        rows = np.flatnonzero(~ok.all(axis=1))
        if len(rows):
            d = self.model.distances(q[rows], where=~ok[rows], near=signs)
            out[rows] = np.where(ok[rows], out[rows], d)
        return out

    def pair_distances(self, q: np.ndarray, pair: np.ndarray, signs: bool = False) -> np.ndarray:
        """(N,) the signed distance [m] of pair `pair[n]` at configuration q[n]: the entries
        `distances(q, signs)[n, pair[n]]`, with only that pair's two shapes placed (a root
        refinement follows one pair: about 1/P of the pair work, a few joints of the tree)."""
        q = np.ascontiguousarray(q, dtype=float)
        pair = np.ascontiguousarray(pair, dtype=np.int64)
        if q.ndim != 2 or q.shape[1] != self.model.robot.model.nq or not np.isfinite(q).all():
            return self.model.distances(q)  # raises the model's error
        out = np.full(len(q), np.nan)
        ok = np.zeros(len(q), dtype=np.bool_)
        if len(q) and len(self._used):
            on_cores(pair_rows_kernel, len(q), PARALLEL_MIN, q, pair, *self.pair_kernel_data(), out, ok)
        if signs:
            ok |= (self.kinds[pair] == PLATE) & (out > 0)
            rows = np.flatnonzero(~ok & np.isin(pair, self._bound_of))
            if len(rows):  # coal pairs whose bounding capsules are apart
                column = np.searchsorted(self._bound_of, pair[rows])
                bound = self._bound.pair_distances(q[rows], column)  # type: ignore[union-attr]
                apart = bound > 0
                out[rows[apart]], ok[rows[apart]] = bound[apart], True
        rows = np.flatnonzero(~ok)
        for k in np.unique(pair[rows]):
            r = rows[pair[rows] == k]
            out[r] = self.model.distances(q[r], only=np.array([k]), near=signs)[:, k]
        return out

    def pair_kernel_data(self) -> tuple[np.ndarray, ...]:
        """`capsule_kernels.pair_rows_kernel`'s arguments after q and pair, before out and ok (the
        tree's joints, the chains, the shapes and the pairs), for kernels that evaluate one pair
        at configurations of their own."""
        t = self._tree
        return (t.parent, t.kind, t.axis, t.idx_q, t.rotation, t.translation, t.chain, t.chain_len, self._joint_of,
                self._local_p, self._local_axis, self._radius, self._half, self._pairs, self.kinds)

    def closed_form_data(self) -> tuple[np.ndarray, ...]:
        """`capsule_kernels.closed_form_kernel`'s arguments after q, before out and ok, for kernels
        that evaluate every pair at configurations of their own."""
        t = self._tree
        return (t.parent, t.kind, t.axis, t.idx_q, t.rotation, t.translation, t.of_geometry, self._used,
                self._local_p, self._local_axis, self._radius, self._half, self._pairs, self.kinds)

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
    for `capsule_kernels.tree_kernel`: each one's parent (index in this list, -1 for the world), kind
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
        # chain[m, :chain_len[m]]: tree joint m's ancestors and itself, parents first (one shape's
        # joints alone, `capsule_kernels.pair_rows_kernel`)
        self.chain = np.zeros((n, max(n, 1)), dtype=np.int64)
        self.chain_len = np.zeros(n, dtype=np.int64)
        for m in range(n):
            up = [m]
            while self.parent[up[-1]] >= 0:
                up.append(int(self.parent[up[-1]]))
            self.chain_len[m] = len(up)
            self.chain[m, :len(up)] = up[::-1]


def _joint_frame(model: Any, joint: int) -> int:
    """The index of joint `joint`'s own frame (placement identity in the joint)."""
    import pinocchio as pin

    return next(f for f, fr in enumerate(model.frames)
                if (fr.parentJoint == joint and fr.type in (pin.FrameType.JOINT, pin.FrameType.FIXED_JOINT)
                and fr.placement.isIdentity()) or (joint == 0 and f == 0))



def kernels() -> tuple[Any, ...]:
    """The compiled kernels (for `kinematics.jit`)."""
    return capsule_kernels.kernels()
