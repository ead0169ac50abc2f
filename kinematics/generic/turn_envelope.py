"""Turn envelopes: coaxial cylinders holding every turn of a fixed body about an axis, so that
the pairs of a body fixed in the world (a serial arm's base link, an obstacle) with bodies carried
by a full-turn base joint can be measured on the arm's (rho, z) profile.

With the base turned by psi about the axis (origin o, unit direction u), a carried body at the
profile's azimuth 0 meets the fixed body F turned by -psi. Over a full turn, F sweeps the solid
of revolution

    S(F) = union over psi of R_u(psi) F,   with profile r_F(z) = max { |p - o - z u| : p in F, (p - o).u = z },

and a carried body clear of S(F) is clear of F at every base angle. A stack of coaxial cylinders
(bands [z_0, z_1] along u, each of radius >= r_F on its band) holds S(F); its pairs with the
carried bodies keep their distances when the base turns.

The profile is bounded per slice [z_a, z_b] of F's extent along u (rho = |p - o - ((p - o).u) u|
is convex in p, so on a convex piece its largest value is at a vertex of the piece):

* a convex polytope (a box, a hull) or a triangle mesh: the largest rho over its vertices inside
  the slab and the points where its edges cross the slab's two planes (the slab's part of a
  polytope has no other vertices; a solid's largest rho at a height lies on its surface, whose
  pieces in the slab are clipped triangles); a mesh is bounded by its own triangles, not its hull;
* a capsule, cylinder or sphere (through its bounding capsule, `bounding.bounding_capsule`: a
  segment thickened by r): the largest rho over the segment's part within [z_a - r, z_b + r],
  plus r.

The SLICES slices are then merged, two neighbours at a time, the pair adding the least volume
first, into at most MAX_BANDS bands (fewer pairs to measure; neighbours of equal radius always),
each band's radius the largest of its slices'. A half-space whose normal is along u is its own solid of revolution (kept as it is);
one tilted from u sweeps nearly all of space and has no useful envelope.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from kinematics.generic.bounding import INFLATE, bounding_capsule, frame_along, polytope_points

SLICES = 64
"""Slices of a fixed body's extent along the axis at which its profile is bounded."""

MAX_BANDS = 4
"""Largest number of coaxial cylinders per enveloped body."""

SIDES = 64
"""Sides of the prism a band is measured as against a polytope (a mesh's hull, a box; `prism`):
coal's penetration depth between a cylinder and a hull fails now and then (EPA returns -DBL_MAX:
28 of 5,318 overlapping entries of the ur5's base bands at random configurations), never between
two convex polytopes; the prism circumscribes the band's cylinder, 0.12 % wider at its corners.
Against a capsule or sphere the band stays a cylinder (closed forms where they apply)."""

COAXIAL_TOL = 1e-9
"""[m, rad] A cylinder or half-space counts as coaxial with (normal along) the axis within this."""


@dataclass(frozen=True)
class Band:
    """A coaxial cylinder: heights lo to hi [m] along the axis from its origin, radius [m]."""

    lo: float
    hi: float
    radius: float


def axial(points: np.ndarray, origin: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Height along the axis and distance from it [m] of world points (K, 3)."""
    v = np.asarray(points, dtype=float).reshape(-1, 3) - origin
    z = v @ axis
    return z, np.linalg.norm(v - np.outer(z, axis), axis=1)


def _polytope_profile(vertices: np.ndarray, edges: np.ndarray, origin: np.ndarray, axis: np.ndarray,
                      cuts: np.ndarray) -> np.ndarray:
    """Largest distance from the axis on each slab [cuts[i], cuts[i+1]] of a convex polytope or a
    closed triangle mesh's solid (world vertices (K, 3), edges (E, 2) vertex indices); -inf where
    the slab misses it."""
    z, rho = axial(vertices, origin, axis)
    n = len(cuts) - 1
    out = np.full(n, -np.inf)
    # every vertex counts in each slab holding its height (both, on a shared plane)
    for i in range(n):
        inside = (z >= cuts[i]) & (z <= cuts[i + 1])
        if inside.any():
            out[i] = rho[inside].max()
    # the edges' crossings of every cut plane count in the two slabs the plane bounds
    a, b = vertices[edges[:, 0]], vertices[edges[:, 1]]
    za, zb = z[edges[:, 0]], z[edges[:, 1]]
    for c, cut in enumerate(cuts):
        cross = (np.minimum(za, zb) < cut) & (np.maximum(za, zb) > cut)
        if not cross.any():
            continue
        t = (cut - za[cross]) / (zb[cross] - za[cross])
        p = a[cross] + t[:, None] * (b[cross] - a[cross])
        r = axial(p, origin, axis)[1].max()
        for i in (c - 1, c):
            if 0 <= i < n:
                out[i] = max(out[i], r)
    return out


def _capsule_profile(p0: np.ndarray, p1: np.ndarray, radius: float, origin: np.ndarray, axis: np.ndarray,
                     cuts: np.ndarray) -> np.ndarray:
    """Largest distance from the axis on each slab of the capsule (segment p0-p1, radius) (module
    docstring); -inf where the slab misses it."""
    (z0, z1), _ = axial(np.stack([p0, p1]), origin, axis)
    out = np.full(len(cuts) - 1, -np.inf)
    for i in range(len(cuts) - 1):
        lo, hi = cuts[i] - radius, cuts[i + 1] + radius
        if max(z0, z1) < lo or min(z0, z1) > hi:
            continue
        if z1 == z0:
            ends = [p0, p1]
        else:  # the segment's part within [lo, hi]: its two ends
            t = np.clip((np.array([lo, hi]) - z0) / (z1 - z0), 0.0, 1.0)
            ends = [p0 + s * (p1 - p0) for s in t]
        out[i] = axial(np.stack(ends), origin, axis)[1].max() + radius
    return out


def _merge(cuts: np.ndarray, radii: np.ndarray, bands: int) -> list[Band]:
    """Neighbouring slices merged (least added volume pi r^2 h first) into at most `bands` bands."""
    # a slice the body misses (-inf: between a mesh's separate parts) costs -inf to merge, so it
    # joins a neighbour first and takes its radius (a looser but valid envelope)
    merged = [[float(cuts[i]), float(cuts[i + 1]), float(radii[i])] for i in range(len(radii))]

    def cost(a: list[float], b: list[float]) -> float:
        r = max(a[2], b[2])
        return r * r * (b[1] - a[0]) - a[2] ** 2 * (a[1] - a[0]) - b[2] ** 2 * (b[1] - b[0])

    while len(merged) > 1:  # past `bands`, neighbours that add nothing (equal radii) still merge
        k = min(range(len(merged) - 1), key=lambda i: cost(merged[i], merged[i + 1]))
        a, b = merged[k], merged[k + 1]
        # equal radii add only rounding
        if len(merged) <= bands and cost(a, b) > 1e-12 * max(a[2], b[2]) ** 2 * (b[1] - a[0]):
            break
        merged[k:k + 2] = [[a[0], b[1], max(a[2], b[2])]]
    return [Band(lo, hi, r * (1.0 + 1e-12) + INFLATE) for lo, hi, r in merged]


def envelope_bands(geometry: Any, placement: Any, origin: np.ndarray, axis: np.ndarray,
                   bands: int = MAX_BANDS, mesh: Any = None) -> list[Band] | None:
    """The coaxial cylinders (module docstring) holding every turn of the coal shape `geometry`
    placed at `placement` (pin.SE3, world frame) about the axis (origin, unit direction), or None
    for a shape with no envelope (a half-space, which is either its own or has none, or a shape
    kind not handled). `mesh`: the triangle mesh (a coal BVH model) whose hull `geometry` is,
    bounded itself (its vertices and triangle edges: the solid's largest rho at a height lies on its
    surface, so the slices' bound is exact for it, and tighter than the hull's)."""
    import coal
    from scipy.spatial import ConvexHull

    R, t = np.asarray(placement.rotation), np.asarray(placement.translation)
    local = polytope_points(geometry)
    if mesh is not None or local is not None:
        if mesh is not None:
            world = np.asarray(mesh.vertices(), dtype=float) @ R.T + t
            faces = np.array([[tri[0], tri[1], tri[2]] for tri in (mesh.tri_indices(i) for i in range(mesh.num_tris))],
                             dtype=np.int64).reshape(-1, 3)
        else:
            world = local @ R.T + t
            faces = ConvexHull(world).simplices
        edges = np.unique(np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [0, 2]]]), axis=1), axis=0)
        z = axial(world, origin, axis)[0]
        cuts = np.linspace(z.min(), z.max(), SLICES + 1)
        return _merge(cuts, _polytope_profile(world, edges, origin, axis, cuts), bands)
    fit = bounding_capsule(geometry)
    if fit is None or isinstance(geometry, coal.Halfspace):
        return None
    centre, direction, radius, half = fit
    c, d = R @ centre + t, R @ direction
    p0, p1 = c - half * d, c + half * d
    z = axial(np.stack([p0, p1]), origin, axis)[0]
    cuts = np.linspace(z.min() - radius, z.max() + radius, SLICES + 1)
    return _merge(cuts, _capsule_profile(p0, p1, radius, origin, axis, cuts), bands)


def coaxial(geometry: Any, placement: Any, origin: np.ndarray, axis: np.ndarray) -> bool:
    """Whether the coal shape at `placement` (world) is unchanged by turns about the axis: a
    cylinder, capsule or sphere centred on it and aligned with it, or a half-space whose normal is
    along it (within COAXIAL_TOL)."""
    import coal

    R, t = np.asarray(placement.rotation), np.asarray(placement.translation)
    if isinstance(geometry, coal.Halfspace):
        n = R @ np.asarray(geometry.n, dtype=float)
        return bool(np.linalg.norm(np.cross(n / np.linalg.norm(n), axis)) <= COAXIAL_TOL)
    if isinstance(geometry, coal.Sphere | coal.Cylinder | coal.Capsule):
        off = axial(t[None, :], origin, axis)[1][0]
        aligned = isinstance(geometry, coal.Sphere) or np.linalg.norm(np.cross(R[:, 2], axis)) <= COAXIAL_TOL
        return bool(off <= COAXIAL_TOL and aligned)
    return False


def prism(radius: float, length: float) -> Any:
    """The regular SIDES-gon prism about the z axis, centred, circumscribing the cylinder of
    `radius` and `length` [m] (its vertices at radius / cos(pi / SIDES)), as a coal convex shape."""
    import coal

    a = np.linspace(0.0, 2.0 * np.pi, SIDES, endpoint=False)
    r = radius / np.cos(np.pi / SIDES) * (1.0 + 1e-12)
    points = coal.StdVec_Vec3s()
    for z in (-0.5 * length, 0.5 * length):
        for t in a:
            points.append(np.array([r * np.cos(t), r * np.sin(t), z]))
    return coal.Convex.convexHull(points, False, "Qt")


@dataclass(frozen=True, eq=False)
class TurnEnvelope:
    """A collision model with every fixed body that pairs with a carried one replaced by its turn
    envelope (`turn_envelope`).

    Attributes:
        model: the enveloped `CollisionModel` (each band a cylinder `<geometry>~<k>` and the prism
            around it `<geometry>~<k>p` (`SIDES`), on the world joint and the fixed body's link;
            its pairs with a polytope use the prism, the others the cylinder); every pair of it keeps its distances when
            the base turns.
        exact: indices of its pairs that are the original model's own (no enveloped body): the
            pairs the upper bound keeps.
        original: (P,) for each pair of `model`, the index of the original model's pair it stands
            for (an enveloped body's pair with a carried body has one pair per band, all standing
            for that pair: its distance is their smallest).
        enveloped: (link, geometry name, bands) of each enveloped body.
    """

    model: Any
    exact: np.ndarray
    original: np.ndarray
    enveloped: tuple[tuple[str, str, tuple[Band, ...]], ...]


def turn_envelope(model: Any, q: np.ndarray, origin: np.ndarray, axis: np.ndarray, carried: set[int],
                  bands: int = MAX_BANDS) -> TurnEnvelope | None:
    """The `CollisionModel` `model` with each body that is not carried (its joint not in
    `carried`, the subtree of the base joint) and not coaxial, paired with a carried body,
    replaced by its turn envelope about (origin, unit axis) [m] (world frame); the fixed bodies
    placed at configuration q (nq,). None when some such body has no envelope (module docstring)."""
    import coal
    import pinocchio as pin

    from kinematics.generic.collision import CollisionModel

    geometry, robot = model.geometry, model.robot
    data = robot.model.createData()
    gdata = pin.GeometryData(geometry)
    pin.updateGeometryPlacements(robot.model, data, geometry, gdata, np.asarray(q, dtype=float))
    objs = list(geometry.geometryObjects)
    fixed = {k for pair in model.pairs for k in pair if int(objs[k].parentJoint) not in carried}
    swap: dict[int, list[Band]] = {}
    for k in sorted(fixed):
        if coaxial(objs[k].geometry, gdata.oMg[k], origin, axis):
            continue
        found = envelope_bands(objs[k].geometry, gdata.oMg[k], origin, axis, bands, model.meshes.get(objs[k].name))
        if found is None:
            return None
        swap[k] = found
    out = pin.GeometryModel()
    index: dict[int, list[int]] = {}  # geometry -> its copies (a band: cylinder, then prism)
    obstacles: dict[int, str] = {}
    frame = frame_along(axis)

    def add(k: int, obj: Any) -> None:
        if k in model.obstacles:
            obstacles[out.ngeoms] = model.obstacles[k]
        index.setdefault(k, []).append(out.ngeoms)
        out.addGeometryObject(obj)

    for k, g in enumerate(objs):
        if k not in swap:
            add(k, pin.GeometryObject(g.name, g.parentJoint, g.parentFrame, g.placement, g.geometry))
            continue
        for n, band in enumerate(swap[k]):
            place = pin.SE3(frame, origin + 0.5 * (band.lo + band.hi) * axis)
            add(k, pin.GeometryObject(f"{g.name}~{n}", 0, g.parentFrame, place,
                                      coal.Cylinder(band.radius, band.hi - band.lo)))
            add(k, pin.GeometryObject(f"{g.name}~{n}p", 0, g.parentFrame, place, prism(band.radius, band.hi - band.lo)))
    exact, original = [], []
    for p, (a, b) in enumerate(model.pairs):
        if a not in swap and b not in swap:
            exact.append(len(out.collisionPairs))
            original.append(p)
            out.addCollisionPair(pin.CollisionPair(index[a][0], index[b][0]))
            continue
        band, other = (a, b) if a in swap else (b, a)
        # a band against a polytope (a mesh's hull, a box) as its prism, else as its cylinder
        polytope = int(isinstance(objs[other].geometry, coal.ConvexBase | coal.Box))
        for n in range(len(swap[band])):
            original.append(p)
            out.addCollisionPair(pin.CollisionPair(index[band][2 * n + polytope], index[other][0]))
    kept = {g.name for g in out.geometryObjects}
    meshes = {name: mesh for name, mesh in model.meshes.items() if name in kept}
    enveloped = tuple((model.links[k], objs[k].name, tuple(b)) for k, b in swap.items())
    return TurnEnvelope(CollisionModel(robot, out, meshes, model.excluded, obstacles),
                        np.array(exact, dtype=np.int64), np.array(original, dtype=np.int64), enveloped)


__all__ = ["COAXIAL_TOL", "MAX_BANDS", "SIDES", "SLICES", "Band", "TurnEnvelope", "axial", "coaxial", "envelope_bands",
           "prism", "turn_envelope"]
