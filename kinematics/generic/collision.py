"""Self-collision (and obstacle) distances of a robot: which pairs of bodies can collide, and
their signed distances over batches of configurations, through coal (via Pinocchio).

Pairs: every pair of collision geometries on different bodies, less

* **adjacent** bodies: on the same joint, joined by one joint (parent and child), or joined by a
  loop closure (the two frames of a closure constraint): they touch by design;
* bodies **touching at the reference configuration** (signed distance <= `TOUCH_TOL`): in contact
  by design, as an SRDF's "Default" disabled pairs;
* pairs **disabled** by the caller or by the loop sidecar's `collisions: disabled:` (link names).

Obstacles (`kinematics.generic.obstacles`): fixed bodies in the world frame, paired with every
moving body of the robot (never adjacent, never left out as touching: the robot must not touch
them; only a disabled pair is left out); without self-collisions only those pairs are checked.

Capsules: URDF has no `<capsule>`; a `<collision>` cylinder with a sphere of its radius centred on
each end face (on the same link) is a capsule written the only way URDF can, and is loaded as one
`coal.Capsule` (the union of the three is exactly that capsule, so no distance changes sign; its
penetration depth is the capsule's own, as the kernels of `kinematics.generic.capsules` compute).

Signed distance [m]: positive apart, negative in penetration. Between primitives (box, cylinder,
sphere) it is coal's GJK/EPA distance, exact. Coal has no penetration depth between triangle
meshes, so a pair with a mesh is measured on the meshes' convex hulls (coal's qhull) first: a hull
contains its mesh, so where the hulls are apart the meshes are too, and the hulls' distance (a lower
bound of the meshes') is the value; where the hulls overlap, the meshes' own collision test decides
the sign: colliding, the hulls' (negative or zero) distance less `CONTACT_EPS`; apart, the meshes'
own distance. The sign is therefore the meshes' own everywhere, the zero set their contact.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from kinematics.chunks import slices
from kinematics.errors import ConvergenceError, InvalidInputError, UnknownNameError

if TYPE_CHECKING:
    from kinematics.generic.coal_pool import CoalPool
    from kinematics.generic.obstacles import Obstacles

CONTACT_EPS = 1e-12
"""Subtracted [m] from a colliding mesh pair's hull distance, so that colliding is always < 0."""

GJK_TOL = 1e-10
"""Coal's GJK/EPA stopping tolerance [m] for every pair (its default, 1e-6, lets a distance come
out up to ~1e-7 m long, e.g. a hull farther than the mesh inside it)."""

NEAR = 1e-3
"""[m] Where only signs matter (`CollisionModel.distances(near=True)`), a mesh pair whose hulls
overlap and whose meshes are at least NEAR apart is reported at NEAR."""

ROWS = 64
"""Configurations per chunk of a distance batch, each from a fresh coal state (`CollisionModel.rows`):
the chunks are the unit of work of the worker processes (`kinematics.generic.coal_pool`), and
fixed, so that the values do not depend on how many processes share a batch (~6 ms of coal a
chunk for the ur5's 20 pairs, against ~0.1 ms for the fresh state)."""

EPA_FAILED = -1e300
"""[m] A distance at or below this is coal's EPA failing on two overlapping shapes (it returns
-DBL_MAX): now and then between cylinders, or a cylinder and a hull (24 of 145,000 entries of the
z1's pairs at random configurations, 3.6 % of the colliding ones), depending on GJK's warm start."""

RETRY_TOLERANCES = (1e-6, 1e-4)
"""[m] The GJK/EPA tolerances a failed EPA (EPA_FAILED) is retried at, from a fresh state, in turn
(at 1e-6 every one of the z1's 24 failures above came out finite, with the sign of the overlap)."""

TOUCH_TOL = 1e-6
"""Distance [m] at or below which two bodies count as touching at the reference configuration."""

Reason = Literal["adjacent", "touching", "disabled"]


@dataclass(frozen=True)
class ExcludedPair:
    """A pair of links left out of the collision checks, and why."""

    first: str
    second: str
    reason: Reason


class CollisionModel:
    """The collision geometry of a robot, the pairs that can collide and their signed distances.

    Build with `CollisionModel.from_robot`. `links[k]` is the link of geometry k; `pairs` are
    geometry index pairs, `pair_names` their geometry names (Pinocchio's `<link>_<k>`),
    `pair_links` their link names.
    """

    def __init__(self, robot: Any, geometry: Any, meshes: Any, excluded: Sequence[ExcludedPair],
                 obstacles: dict[int, str] | None = None) -> None:
        self.robot = robot
        self.geometry = geometry
        self.meshes = meshes
        self.excluded = tuple(excluded)
        self.obstacles = dict(obstacles or {})
        """Geometry index -> obstacle body, for the geometries that are obstacles."""
        self.links = tuple(self.obstacles.get(k, robot.model.frames[g.parentFrame].name)
                           for k, g in enumerate(geometry.geometryObjects))
        self.pairs = tuple((int(p.first), int(p.second)) for p in geometry.collisionPairs)
        self.pair_links = tuple((self.links[a], self.links[b]) for a, b in self.pairs)
        names = [g.name for g in geometry.geometryObjects]
        self.pair_names = tuple((names[a], names[b]) for a, b in self.pairs)
        self._data = robot.model.createData()
        # the pairs with a mesh, checked again on the meshes themselves (same pair order)
        mesh_pairs = [n for n, (a, b) in enumerate(self.pairs)
                      if geometry.geometryObjects[a].name in meshes or geometry.geometryObjects[b].name in meshes]
        self._mesh_pairs = np.array(mesh_pairs, dtype=np.int64)
        self._mesh_model = _mesh_model(robot, geometry, self.pairs, meshes) if mesh_pairs else None
        self._inline_seconds = 0.0
        self._workers: CoalPool | Literal[False] | None = None  # False: no pool can start

    @classmethod
    def from_robot(cls, robot: Any, *, disabled: Iterable[tuple[str, str]] = (),
                   reference: np.ndarray | None = None, exclude_touching: bool = True,
                   urdf_text: str | None = None, obstacles: Obstacles | None = None,
                   self_collisions: bool = True) -> CollisionModel:
        """Load `robot`'s collision geometry and choose the pairs to check.

        Args:
            robot: a loaded `Robot`; its URDF's `<collision>` elements are read (`GeometryError`
                if one cannot be: an unknown shape or a missing mesh).
            disabled: link-name pairs never checked (order does not matter).
            reference: configuration (nq,) at which touching pairs are found (default: the loop
                sidecar's reference configuration, else the neutral one); it should be a valid,
                closed pose.
            exclude_touching: leave out pairs touching at `reference`.
            urdf_text: URDF text to read the geometry from instead of the robot's file.
            obstacles: fixed bodies in the world (`load_obstacles`), checked against every
                moving body; their names must differ from the robot's links.
            self_collisions: check pairs of the robot's own bodies (False: obstacle pairs only).
        """
        import pinocchio as pin

        from kinematics.model.geometry import geometry_model

        geometry = _merge_capsules(geometry_model(robot, "collision", urdf_text=urdf_text)[0])
        model = robot.model
        links = [model.frames[g.parentFrame].name for g in geometry.geometryObjects]
        taken = {f.name for f in model.frames}
        on_obstacle = _add_obstacles(geometry, obstacles, taken) if obstacles is not None else {}
        links = [*links, *on_obstacle.values()]
        meshes = _convexify(geometry)
        loops = getattr(robot, "loops", None)
        disabled = [*disabled, *getattr(loops, "disabled_collisions", ())]
        known = sorted(set(links))
        off = set()
        for a, b in disabled:
            for name in (a, b):
                if name not in known:
                    raise UnknownNameError(name, known)
            off.add(frozenset((a, b)))
        adjacent = _adjacent_joints(robot)
        excluded: list[ExcludedPair] = []
        seen: set[frozenset[str]] = set()
        for i in range(geometry.ngeoms):
            for k in range(i + 1, geometry.ngeoms):
                ji, jk = (geometry.geometryObjects[n].parentJoint for n in (i, k))
                key = frozenset((links[i], links[k]))
                world = (i in on_obstacle) + (k in on_obstacle)  # how many of the two are obstacles
                if ji == jk or (world == 0 and not self_collisions):
                    continue  # one rigid body (or both fixed in the world): no relative motion
                reason: Reason | None = ("adjacent" if world == 0 and frozenset((ji, jk)) in adjacent
                                         else "disabled" if key in off else None)
                if reason is None:
                    geometry.addCollisionPair(pin.CollisionPair(i, k))
                elif key not in seen:
                    seen.add(key)
                    excluded.append(ExcludedPair(links[i], links[k], reason))
        out = cls(robot, geometry, meshes, excluded, on_obstacle)
        if exclude_touching and out.pairs:
            q0 = reference_configuration(robot) if reference is None else np.asarray(reference, dtype=float)
            d0 = out.distances(q0[None, :])[0]
            touching = [n for n, (a, b) in enumerate(out.pairs)
                        if d0[n] <= TOUCH_TOL and a not in on_obstacle and b not in on_obstacle]
            if touching:
                for n in reversed(touching):
                    geometry.removeCollisionPair(geometry.collisionPairs[n])
                keys = {frozenset(out.pair_links[n]) for n in touching}
                more = [ExcludedPair(a, b, "touching") for a, b in (sorted(k) for k in keys if k not in seen)]
                out = cls(robot, geometry, meshes, [*excluded, *sorted(more, key=lambda e: (e.first, e.second))],
                          on_obstacle)
        return out

    def distances(self, q: np.ndarray, only: np.ndarray | None = None, where: np.ndarray | None = None,
                  near: bool = False) -> np.ndarray:
        """Signed distance [m] of every pair at each configuration.

        Args:
            q: (N, nq) configurations.
            only: pair indices: compute these alone (the other columns are NaN).
            where: (N, P) booleans: compute these entries alone (the others are NaN); with `only`,
                within its pairs.
            near: a mesh pair whose hulls overlap and whose meshes are NEAR or more apart (coal's
                collision test with that security margin) gets NEAR instead of the meshes' own
                distance: min(d, NEAR), continuous, exact below NEAR (a mesh distance costs ~10x
                a collision test: the ur5's base and upper arm 280 us against 17 us).

        Returns:
            (N, P) distances, pair order as `pairs`; (N, 0) when no pair can collide.
        """
        q = np.asarray(q, dtype=float)
        nq = self.robot.model.nq
        if q.ndim != 2 or q.shape[1] != nq or not np.isfinite(q).all():
            raise InvalidInputError("q", f"expected finite configurations of shape (N, {nq}), got {q.shape}")
        pick = None
        if only is not None or where is not None:
            pick = np.zeros((len(q), len(self.pairs)), dtype=bool)
            pick[:, np.arange(len(self.pairs)) if only is None else np.asarray(only, dtype=np.int64)] = True
            if where is not None:
                pick &= np.asarray(where, dtype=bool).reshape(pick.shape)
        out = np.empty((len(q), len(self.pairs)))
        spans = list(slices(len(q), ROWS))
        pool = self._pool(len(spans))
        if pool is not None:
            for span, d in zip(spans, pool.map(q, pick, near, spans), strict=True):
                out[span] = d
            return out
        start = time.perf_counter()
        for span in spans:
            out[span] = self.rows(q[span], None if pick is None else pick[span], near)
        self._inline_seconds += time.perf_counter() - start
        return out

    def rows(self, q: np.ndarray, pick: np.ndarray | None = None, near: bool = False) -> np.ndarray:
        """`distances` of one chunk of configurations q (N, nq) (valid), `pick` (N, P) the entries
        to compute (None: all; the others NaN), from a fresh coal state (new `GeometryData`: coal's
        GJK warm starts otherwise carry the previous call's last bits into this one's), so that a
        chunk's values are the same in whichever process and order it is evaluated."""
        import pinocchio as pin

        out = np.empty((len(q), len(self.pairs)))
        gdata = _tight(pin.GeometryData(self.geometry))
        results = gdata.distanceResults
        model, data = self.robot.model, self._data
        if pick is not None:
            out[:] = np.nan
        mesh_data = near_data = None
        for n, qn in enumerate(q):
            if pick is None:
                pin.computeDistances(model, data, self.geometry, gdata, qn)
                out[n] = [r.min_distance for r in results]
            else:
                pairs = np.flatnonzero(pick[n])
                if not len(pairs):
                    continue
                pin.updateGeometryPlacements(model, data, self.geometry, gdata, qn)
                for k in pairs:
                    out[n, k] = pin.computeDistance(self.geometry, gdata, int(k)).min_distance
            failed = np.flatnonzero(out[n] <= EPA_FAILED)
            if len(failed):
                out[n, failed] = self._retry(qn, failed)
            if self._mesh_model is None:
                continue
            mesh = self._mesh_pairs if pick is None else self._mesh_pairs[pick[n, self._mesh_pairs]]
            overlap = mesh[out[n, mesh] <= 0.0]
            if len(overlap):
                if mesh_data is None:
                    mesh_data = _tight(pin.GeometryData(self._mesh_model))
                    near_data = _tight(pin.GeometryData(self._mesh_model), NEAR)
                pin.updateGeometryPlacements(model, data, self._mesh_model, mesh_data)
                if near:
                    pin.updateGeometryPlacements(model, data, self._mesh_model, near_data)
                for k in overlap:
                    if near and not pin.computeCollision(self._mesh_model, near_data, int(k)):
                        out[n, k] = NEAR
                    elif pin.computeCollision(self._mesh_model, mesh_data, int(k)):
                        out[n, k] -= CONTACT_EPS
                    else:
                        out[n, k] = pin.computeDistance(self._mesh_model, mesh_data, int(k)).min_distance
        return out

    def _retry(self, q: np.ndarray, pairs: np.ndarray) -> np.ndarray:
        """The distances [m] of `pairs` at configuration q (nq,) whose EPA failed (coal returned
        -DBL_MAX for two overlapping shapes), again from fresh states at each of RETRY_TOLERANCES
        in turn (`ConvergenceError` if every one fails)."""
        import pinocchio as pin

        out = np.full(len(pairs), -np.inf)
        for tol in RETRY_TOLERANCES:
            gdata = _tight(pin.GeometryData(self.geometry), tol=tol)
            pin.updateGeometryPlacements(self.robot.model, self._data, self.geometry, gdata, q)
            for n in np.flatnonzero(out <= EPA_FAILED):
                out[n] = pin.computeDistance(self.geometry, gdata, int(pairs[n])).min_distance
            if (out > EPA_FAILED).all():
                return out
        bad = [self.pair_names[k] for k in pairs[out <= EPA_FAILED]]
        raise ConvergenceError(f"coal's penetration depth of {bad} at q = {np.round(q, 6).tolist()}",
                               len(RETRY_TOLERANCES), math.inf, RETRY_TOLERANCES[-1])

    def _pool(self, chunks: int) -> CoalPool | None:
        """The worker processes for a call of `chunks` chunks (`coal_pool.CoalPool.start`): started
        once this model has spent `coal_pool.START_AFTER` in coal inline; None: evaluate inline."""
        from kinematics.generic import coal_pool

        if self._workers is None and chunks > 1 and self._inline_seconds >= coal_pool.START_AFTER:
            self._workers = coal_pool.CoalPool.start(self) or False
        return (self._workers or None) if chunks > 1 else None

    def margin(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Smallest signed distance [m] over the pairs, and the index of the pair that has it
        (-1, with +inf, where no pair can collide). Negative: the configuration collides."""
        d = self.distances(q)
        if d.shape[1] == 0:
            return np.full(len(d), np.inf), np.full(len(d), -1)
        k = np.argmin(d, axis=1)
        return d[np.arange(len(d)), k], k

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready summary: geometries, checked pairs and excluded pairs with reasons."""
        return {
            "geometries": [g.name for g in self.geometry.geometryObjects],
            "obstacles": list(dict.fromkeys(self.obstacles.values())),
            "pairs": [{"geometries": list(g), "links": list(k)} for g, k in zip(self.pair_names, self.pair_links, strict=True)],
            "excluded": [{"first": e.first, "second": e.second, "reason": e.reason} for e in self.excluded],
        }


def reference_configuration(robot: Any) -> np.ndarray:
    """The loop sidecar's reference configuration (nq,) (the neutral value for joints it does not
    name), or the neutral configuration when there is no sidecar."""
    import pinocchio as pin

    model = robot.model
    q = pin.neutral(model)
    loops = getattr(robot, "loops", None)
    for name, value in getattr(loops, "reference", {}).items():
        j = model.getJointId(name)
        i, nq = model.idx_qs[j], model.nqs[j]
        q[i:i + nq] = [value] if nq == 1 else [np.cos(value), np.sin(value)]
    return q


def _merge_capsules(geometry: Any) -> Any:
    """`geometry` with every cylinder that has a sphere of its radius centred on each end face
    (same frame) replaced by one `coal.Capsule` (named as the cylinder), the spheres removed."""
    import coal
    import pinocchio as pin

    objs = list(geometry.geometryObjects)
    spheres = [k for k, g in enumerate(objs) if isinstance(g.geometry, coal.Sphere)]
    used: set[int] = set()
    capsule_of: dict[int, Any] = {}
    for k, g in enumerate(objs):
        if not isinstance(g.geometry, coal.Cylinder):
            continue
        r, h = g.geometry.radius, g.geometry.halfLength
        ends = [g.placement.translation + s * h * g.placement.rotation[:, 2] for s in (-1.0, 1.0)]
        found = []
        for end in ends:
            match = next((n for n in spheres if n not in used and n not in found and objs[n].parentFrame == g.parentFrame
                          and abs(objs[n].geometry.radius - r) <= 1e-12 * r
                          and np.linalg.norm(objs[n].placement.translation - end) <= 1e-9), None)
            found.append(match)
        if None not in found:
            used.update(n for n in found if n is not None)
            capsule_of[k] = coal.Capsule(r, 2.0 * h)
    if not capsule_of:
        return geometry
    out = pin.GeometryModel()
    for k, g in enumerate(objs):
        if k not in used:
            out.addGeometryObject(pin.GeometryObject(g.name, g.parentJoint, g.parentFrame, g.placement,
                                                     capsule_of.get(k, g.geometry)))
    return out


def _add_obstacles(geometry: Any, obstacles: Obstacles, taken: set[str]) -> dict[int, str]:
    """Append the obstacles' geometries (capsules merged) to `geometry`, on joint 0; returns
    geometry index -> obstacle body. Raises `InvalidInputError` if a name is the robot's."""
    import pinocchio as pin

    body = dict(zip((g.name for g in obstacles.geometry.geometryObjects), obstacles.links, strict=True))
    names = {g.name for g in geometry.geometryObjects}
    out = {}
    for g in _merge_capsules(obstacles.geometry).geometryObjects:
        if g.name in names or body[g.name] in taken:
            raise InvalidInputError("obstacles", f"{body[g.name]} ({g.name}) is also a name of the robot's; rename it")
        out[geometry.ngeoms] = body[g.name]
        geometry.addGeometryObject(pin.GeometryObject(g.name, 0, 0, g.placement, g.geometry))
    return out


def _tight(data: Any, margin: float = 0.0, tol: float = GJK_TOL) -> Any:
    """`data` with every pair's GJK/EPA tolerance set to `tol` [m], its collision tests'
    security margin to `margin` [m] (a pair within it counts as colliding)."""
    for request in data.distanceRequests:
        request.gjk_tolerance = request.epa_tolerance = tol
    for request in data.collisionRequests:
        request.security_margin = margin
    return data


def _convexify(geometry: Any) -> dict[str, Any]:
    """Replace every mesh by its convex hull, in place (coal's penetration depths need convex
    shapes); returns the meshes by geometry name."""
    import coal

    meshes = {}
    for g in geometry.geometryObjects:
        if isinstance(g.geometry, coal.BVHModelBase):
            _check_solid(g.name, np.asarray(g.geometry.vertices(), dtype=float))
            meshes[g.name] = g.geometry
            g.geometry.buildConvexHull(True, "Qt")
            g.geometry = g.geometry.convex
    return meshes


FLAT = 1e-6
"""A mesh whose vertices span less than this fraction of their extent across their flattest
direction is flat: coal's convex hull (qhull) crashes the process (a segmentation fault) on
one thinner than about 5e-8 of its extent (a mesh scaled by 0 along an axis, a plate modelled
as one face), so such a mesh is refused."""


def _check_solid(name: str, vertices: np.ndarray) -> None:
    """Raise `InvalidInputError` if the mesh `name`'s vertices (N, 3) [m] are flat (`FLAT`): their
    span along their least-spread principal axis against that along their most-spread one."""
    spans = np.zeros(3)
    if len(vertices) >= 4:
        centred = vertices - vertices.mean(axis=0)
        spans = np.ptp(centred @ np.linalg.svd(centred, full_matrices=False)[2].T, axis=0)
    if not spans[2] > FLAT * spans[0]:
        raise InvalidInputError(f"collision mesh {name}", (
            f"flat: its {len(vertices)} vertices are {spans[2]:.3g} m thick across {spans[0]:.3g} m (a scale of 0, "
            "or a single face?); coal's convex hull needs a solid: give it a thickness or a primitive shape"))


def _mesh_model(robot: Any, hulls: Any, pairs: Sequence[tuple[int, int]], meshes: dict[str, Any]) -> Any:
    """A copy of the hulls' geometry model with the meshes back in place and the same pairs."""
    import pinocchio as pin

    model = pin.GeometryModel()
    for g in hulls.geometryObjects:
        model.addGeometryObject(pin.GeometryObject(g.name, g.parentJoint, g.parentFrame, g.placement,
                                                   meshes.get(g.name, g.geometry)))
    for a, b in pairs:
        model.addCollisionPair(pin.CollisionPair(a, b))
    return model


def _adjacent_joints(robot: Any) -> set[frozenset[int]]:
    """Joint pairs whose bodies touch by design: parent and child, and the two bodies of every loop
    closure (their frames' joints)."""
    model = robot.model
    out = {frozenset((j, int(model.parents[j]))) for j in range(1, model.njoints)}
    loops = getattr(robot, "loops", None)
    for closure in getattr(loops, "closures", ()):
        j1, j2 = (int(model.frames[robot.frame_id(f)].parentJoint) for f in (closure.frame1, closure.frame2))
        out.add(frozenset((j1, j2)))
    return out
