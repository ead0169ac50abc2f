"""Mobility of a mechanism three ways: Grübler–Kutzbach, screw theory, and the numeric rank of
the loop-constraint Jacobian. Works on any robot model plus its loop sidecar.

Conventions. A twist is T = (v_O; w) — the velocity of the body point at the world origin O and
the angular velocity — which is Pinocchio's WORLD-frame Jacobian column. A wrench is
W = (f; m_O), force and moment about O. They are reciprocal when W . T = f.v_O + m_O.w = 0 (the
plain dot product in this ordering), i.e. the wrench does no work on the twist.

Physical links and joints (for the counts) come from the URDF tree: a massless intermediate body
whose single child joint sits at the same origin is the cross of a composite joint, so revolute
chains through such bodies merge into U (2 R) and S (3 R) joints. Each loop closure is a joint:
`point` a spherical joint (3 freedoms; in a planar mechanism it acts as a pin, 1), `6d` a weld (0).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Any, Literal, NamedTuple

import numpy as np
import pinocchio as pin

from kinematics.generic.serial import common_axis, length_scale
from kinematics.model.robot import Robot, matrix

RANK_RTOL = 1e-9
"""Rank tolerance of every decomposition here: singular values <= RANK_RTOL * the largest count
as zero. Reported with the singular-value gap so that a near-singular pose is visible."""

_ORIGIN_TOL = 1e-12

TRANSLATION_RTOL = 1e-6
"""A twist (v_E; w), v_E the velocity of the end-effector point E, is a pure translation when
|w| L <= TRANSLATION_RTOL |v_E| (L: the model's `length_scale`): while E travels L the body turns
by at most 1e-6 rad, i.e. a rotation's axis would be more than 10^6 L away (110 km for
robot_delta, L = 0.11 m). E counts as moving along a freedom when |v_E| > TRANSLATION_RTOL L |w|.
Dually a wrench (f; m_E), m_E the moment about E, is a pure couple when |f| L <= TRANSLATION_RTOL
|m_E| (a force's line would be more than 10^6 L away).

Why 1e-6: the analysed pose is closed only to the solver's tolerance eps (1e-12 m), and a tangent
space computed eps off the loop manifold is off by about kappa(K) eps / L (kappa: the condition
number of the constraint Jacobian's kept singular values). For robot_delta at actuators (0, 0):
kappa = 3.3 / 8.8e-4 = 3.7e3, eps = 7.9e-13 m, L = 0.11 m -> 2.7e-8; measured |w| L / |v_E| =
2.0e-8 on the translation the old classification called a rotation about an axis 5.4e6 m away.
1e-6 is 50 times above that, and 10^6 model sizes is far beyond any axis a real mechanism has."""

REGULAR_RTOL = 1e-3
"""A serial configuration is *regular* when its tool Jacobian has the arm's generic rank r and
sigma_r / sigma_1 > REGULAR_RTOL (well away from a singularity, not merely off it)."""

REGULAR_SEED = 0
"""Seed of the random configurations `regular_configuration` draws."""


class RegularConfiguration(NamedTuple):
    """A serial arm's analysis configuration and what was checked about it.

    Attributes:
        q: Pinocchio configuration.
        values: one value per degree of freedom [rad or m].
        generic_rank: the largest rank of the tool's 6 x nv Jacobian over the samples.
        conditioning: sigma_r / sigma_1 of the tool Jacobian at q (r = generic_rank).
    """

    q: np.ndarray
    values: np.ndarray
    generic_rank: int
    conditioning: float


def _tool_jacobian(robot: Robot, q: np.ndarray) -> np.ndarray:
    model = robot.model
    return matrix(pin.computeFrameJacobian(model, model.createData(), q, robot.frame_id(), pin.LOCAL_WORLD_ALIGNED),
                  model.nv)


def _samples(robot: Robot, n: int, seed: int) -> np.ndarray:
    """n seeded random joint-value vectors within the limits (continuous joints: [-pi, pi))."""
    lo, hi = robot.lower.copy(), robot.upper.copy()
    free = ~(np.isfinite(lo) & np.isfinite(hi))
    lo[free], hi[free] = -np.pi, np.pi
    return np.random.default_rng(seed).uniform(lo, hi, (n, robot.nv))


@functools.lru_cache(maxsize=32)
def regular_configuration(robot: Robot, seed: int = REGULAR_SEED, tries: int = 64) -> RegularConfiguration:
    """A seeded random configuration within the joint limits where the serial arm is regular.

    The generic rank is the largest rank of the tool Jacobian over `tries` random samples (a
    singular pose has measure zero, so one regular sample suffices); the first sample with that
    rank and conditioning above REGULAR_RTOL is returned, else the best conditioned one. The
    middle of the joint ranges is a poor default: for UR5 it is q = 0, a singular pose.
    """
    samples = _samples(robot, tries, seed)
    svals = [np.linalg.svd(_tool_jacobian(robot, robot.configuration(v)), compute_uv=False) for v in samples]
    generic = max(_rank(s) for s in svals)
    cond = np.array([s[generic - 1] / s[0] if generic and _rank(s) == generic else 0.0 for s in svals])
    k = int(np.argmax(cond > REGULAR_RTOL)) if np.any(cond > REGULAR_RTOL) else int(np.argmax(cond))
    return RegularConfiguration(robot.configuration(samples[k]), samples[k], generic, float(cond[k]))


# -- the joint graph ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Edge:
    """A joint of the graph between two Pinocchio bodies (0 = ground).

    Attributes:
        name: joint or closure name.
        kind: "joint" (tree) or "point"/"6d" (loop closure).
        parent, child: body indices; the twist is the child's motion relative to the parent.
        dofs: columns of this edge's freedoms in the graph's rate vector.
    """

    name: str
    kind: str
    parent: int
    child: int
    dofs: tuple[int, ...]


@dataclass
class JointGraph:
    """Bodies, joints (tree + closures) and their twists at one configuration."""

    edges: list[Edge]
    twists: np.ndarray  # 6 x n_rates, WORLD frame (v_O; w)
    platform: int  # body carrying the end-effector frame
    n_bodies: int


def joint_graph(robot: Robot, q: np.ndarray) -> JointGraph:
    """The body graph of a robot at configuration q, with every joint's twists."""
    model = robot.model
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    pin.framesForwardKinematics(model, data, q)
    edges: list[Edge] = []
    columns: list[np.ndarray] = []
    for jid in range(1, model.njoints):
        joint = model.joints[jid]
        J = matrix(pin.getJointJacobian(model, data, jid, pin.WORLD), model.nv)[:, joint.idx_v : joint.idx_v + joint.nv]
        start = len(columns)
        columns.extend(J.T)
        edges.append(Edge(model.names[jid], "joint", int(model.parents[jid]), jid,
                          tuple(range(start, start + joint.nv))))
    if robot.loops is not None:
        for c in robot.loops.closures:
            f1 = robot.frame_id(c.frame1)
            f2 = robot.frame_id(c.frame2)
            start = len(columns)
            if c.type == "point":
                centre = data.oMf[f1].translation
                for axis in np.eye(3):  # rotations about the closure point
                    columns.append(np.concatenate([np.cross(centre, axis), axis]))
            edges.append(Edge(c.name, c.type, int(model.frames[f1].parentJoint), int(model.frames[f2].parentJoint),
                              tuple(range(start, len(columns)))))
    ee = robot.loops.end_effector if robot.loops is not None else robot.tool_frame
    platform = int(model.frames[robot.frame_id(ee)].parentJoint)
    twists = np.array(columns).T if columns else np.zeros((6, 0))
    return JointGraph(edges, twists, platform, model.njoints)


# -- Grübler–Kutzbach ---------------------------------------------------------------------------
@dataclass(frozen=True)
class PhysicalJoint:
    """A joint of the physical mechanism (composite joints merged; closures included)."""

    name: str
    type: str  # R, P, U, S, C, weld, or "<n>-DOF"
    freedoms: int
    members: tuple[str, ...]


@dataclass(frozen=True)
class GrublerCount:
    """M = lambda (links - joints - 1) + sum of joint freedoms."""

    links: int
    joints: int
    freedoms: int
    lam: int
    mobility: int
    planar: bool
    joint_list: tuple[PhysicalJoint, ...]

    def as_dict(self) -> dict[str, Any]:
        types: dict[str, int] = {}
        for j in self.joint_list:
            types[j.type] = types.get(j.type, 0) + 1
        return {"links": self.links, "joints": self.joints, "freedoms": self.freedoms, "lambda": self.lam,
                "mobility": self.mobility, "planar": self.planar, "joint_types": types}


def _composite_type(kinds: list[str]) -> str:
    if len(kinds) == 1:
        return "P" if kinds[0] == "prismatic" else "R"
    if all(k == "revolute" for k in kinds) and len(kinds) in (2, 3):
        return "U" if len(kinds) == 2 else "S"
    if sorted(kinds) == ["prismatic", "revolute"]:
        return "C"
    return f"{len(kinds)}-DOF"


def grubler(robot: Robot, q: np.ndarray | None = None) -> GrublerCount:
    """Grübler–Kutzbach count of the physical mechanism (planar lambda = 3 when every revolute
    axis is parallel at q, else 6; a point closure then acts as a pin, a 6d closure as a weld)."""
    model = robot.model
    q = pin.neutral(model) if q is None else q
    kinds = {d.name: d.kind for d in robot.dofs}
    children: dict[int, list[int]] = {}
    for jid in range(1, model.njoints):
        children.setdefault(int(model.parents[jid]), []).append(jid)
    anchored = set()  # bodies that carry a closure or the end effector: never a joint cross
    frames = [robot.frame_id(c.frame1) for c in (robot.loops.closures if robot.loops else ())]
    frames += [robot.frame_id(c.frame2) for c in (robot.loops.closures if robot.loops else ())]
    frames.append(robot.frame_id(robot.loops.end_effector if robot.loops else robot.tool_frame))
    for f in frames:
        anchored.add(int(model.frames[f].parentJoint))

    def is_cross(body: int) -> bool:
        kids = children.get(body, [])
        return bool(body != 0 and body not in anchored and len(kids) == 1
                    and np.linalg.norm(model.jointPlacements[kids[0]].translation) <= _ORIGIN_TOL)

    # A weld (6d closure) keeps a planar mechanism planar: it removes the welded body's 3 planar
    # freedoms just as it removes 6 spatial ones, so lambda = 3 holds whatever the closure types.
    planar = common_axis(model, q) is not None
    joints: list[PhysicalJoint] = []
    bodies = {0}
    for jid in range(1, model.njoints):
        if is_cross(int(model.parents[jid])):
            continue  # inside a composite joint that starts higher up
        chain = [jid]
        while is_cross(chain[-1]):
            chain.append(children[chain[-1]][0])
        bodies.add(chain[-1])
        names = [model.names[j] for j in chain]
        joints.append(PhysicalJoint(names[0], _composite_type([kinds[n] for n in names]),
                                    sum(model.joints[j].nv for j in chain), tuple(names)))
    for c in robot.loops.closures if robot.loops else ():
        if c.type == "point":
            joints.append(PhysicalJoint(c.name, "R" if planar else "S", 1 if planar else 3, (c.name,)))
        else:
            joints.append(PhysicalJoint(c.name, "weld", 0, (c.name,)))
    lam = 3 if planar else 6
    total = sum(j.freedoms for j in joints)
    links = len(bodies)
    return GrublerCount(links, len(joints), total, lam, lam * (links - len(joints) - 1) + total, planar, tuple(joints))


# -- linear algebra helpers --------------------------------------------------------------------
def _rank(s: np.ndarray, rtol: float = RANK_RTOL) -> int:
    return int(np.sum(s > rtol * s[0])) if s.size and s[0] > 0 else 0


def _orth(A: np.ndarray, rtol: float = RANK_RTOL, scale: float | None = None) -> np.ndarray:
    """Orthonormal basis (columns) of the column space of A; singular values count when above
    rtol * scale (default: A's largest, which is wrong for a residual that should vanish)."""
    if A.size == 0:
        return np.zeros((A.shape[0], 0))
    U, s, _ = np.linalg.svd(A, full_matrices=False)
    ref = s[0] if scale is None else scale
    return U[:, : int(np.sum(s > rtol * ref))]


def _null(A: np.ndarray, rtol: float = RANK_RTOL, scale: float | None = None) -> np.ndarray:
    """Orthonormal basis (columns) of the null space of A (n columns -> n - rank vectors)."""
    n = A.shape[1]
    if A.shape[0] == 0 or not np.any(A):
        return np.eye(n)
    _, s, Vt = np.linalg.svd(A, full_matrices=True)
    ref = s[0] if scale is None else scale
    r = int(np.sum(s > rtol * ref))
    return Vt[r:].T


# -- screw theory --------------------------------------------------------------------------------
@dataclass(frozen=True)
class Wrench:
    """A constraint wrench: a pure couple (f = 0) or a force along a line."""

    type: Literal["force", "couple"]
    axis: np.ndarray  # unit direction of the force or of the couple's moment
    point: np.ndarray | None  # a point of the force's line (None for couples)
    vector: np.ndarray  # (f; m_O), unit norm
    limb: str = ""

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"type": self.type, "axis": self.axis}
        if self.point is not None:
            out["point"] = self.point
        if self.limb:
            out["limb"] = self.limb
        return out


@dataclass(frozen=True)
class Freedom:
    """A platform freedom: a pure translation, or a rotation (screw) about an axis.

    Attributes:
        type: "translation" (|w| L <= TRANSLATION_RTOL |v_E|) or "rotation".
        axis: unit direction of the translation, or of the rotation's angular velocity.
        point: for a rotation, the point of its axis nearest the end-effector point [m] (world).
        pitch: for a rotation, translation along the axis per radian turned [m/rad].
    """

    type: Literal["translation", "rotation"]
    axis: np.ndarray
    point: np.ndarray | None = None
    pitch: float | None = None

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"type": self.type, "axis": self.axis}
        if self.type == "rotation":
            out |= {"point": self.point, "pitch": self.pitch}
        return out


@dataclass(frozen=True)
class Limb:
    """One limb: the joints between ground and platform through one connected sub-mechanism."""

    name: str
    joints: tuple[str, ...]
    paths: int  # sub-chains from ground to platform (2 for a parallelogram limb)
    twist_rank: int
    wrenches: tuple[Wrench, ...]


@dataclass(frozen=True)
class ScrewAnalysis:
    """Constraint wrenches per limb, their union, and the platform's reciprocal twist space.

    Attributes:
        limbs: each limb's joints and constraint wrenches.
        constraint_rank: independent constraint wrenches of all limbs together.
        freedoms: the platform's twist space, translations first (`classify_twists`).
        point_axes: orthonormal directions (unit, world) in which those twists move the
            end-effector point; a point end effector (a five-bar's tip) has these translations
            even where its body also turns.
        length: the model's length scale L [m] the classification was relative to.
    """

    limbs: tuple[Limb, ...]
    constraint_rank: int
    freedoms: tuple[Freedom, ...]
    point_axes: tuple[np.ndarray, ...] = ()
    length: float = 1.0

    @property
    def translations(self) -> int:
        return sum(f.type == "translation" for f in self.freedoms)

    @property
    def rotations(self) -> int:
        return sum(f.type == "rotation" for f in self.freedoms)

    @property
    def point_translations(self) -> int:
        """How many independent directions the end-effector point moves in."""
        return len(self.point_axes)

    def as_dict(self) -> dict[str, Any]:
        wrenches = [w for limb in self.limbs for w in limb.wrenches]
        return {
            "translations": self.translations,
            "rotations": self.rotations,
            "freedoms": [f.as_dict() for f in self.freedoms],
            "point_translations": self.point_translations,
            "point_axes": list(self.point_axes),
            "length_scale": self.length,
            "constraint_wrenches": [w.as_dict() for w in wrenches],
            "constraint_rank": self.constraint_rank,
            "limbs": [{"name": lb.name, "joints": list(lb.joints), "paths": lb.paths, "twist_rank": lb.twist_rank,
                       "constraint_wrenches": [w.as_dict() for w in lb.wrenches]} for lb in self.limbs],
        }


def classify_wrenches(W: np.ndarray, point: np.ndarray, length: float, limb: str = "",
                      rtol: float = TRANSLATION_RTOL) -> list[Wrench]:
    """Split a wrench system into pure couples and forces, couples first: the dual of
    `classify_twists`.

    The wrenches are moved to `point` (m_E = m_O - E x f) and scaled to (f; m_E / L), both [N];
    in an orthonormal basis of that space the SVD of the force block orders the basis wrenches by
    |f|. Those with |f| L <= rtol |m_E| are couples about m_E; the others are forces along f,
    through the point of their line nearest E (E + f x m_E / |f|^2).

    Args:
        W: 6 x k wrenches (f; m_O) spanning the system, independent columns [N; N m].
        point: the end-effector point E [m] (world).
        length: the model's length scale L [m].
        limb: the limb's name, kept on each wrench.
        rtol: see TRANSLATION_RTOL.
    """
    k = W.shape[1]
    if k == 0:
        return []
    f = W[:3]
    mE = W[3:] - np.cross(point, f.T).T
    U, _, _ = np.linalg.svd(np.vstack([f, mE / length]), full_matrices=False)
    Q = U[:, :k]
    _, sf, Vt = np.linalg.svd(Q[:3], full_matrices=True)
    sf = np.concatenate([sf, np.zeros(k - sf.size)])
    B = Q @ Vt.T  # basis wrenches ordered by |f| descending, scaled (f; m_E / L)
    out = []
    for col in B[:, sf <= rtol].T:
        m = col[3:] * length
        vec = np.concatenate([col[:3], m + np.cross(point, col[:3])])  # back to (f; m_O)
        out.append(Wrench("couple", _canonical(m / np.linalg.norm(m)), None, vec / np.linalg.norm(vec), limb))
    for col in B[:, sf > rtol][:, ::-1].T:
        fo, m = col[:3], col[3:] * length
        nf2 = float(fo @ fo)
        vec = np.concatenate([fo, m + np.cross(point, fo)])
        out.append(Wrench("force", _canonical(fo / np.sqrt(nf2)), point + np.cross(fo, m) / nf2,
                          vec / np.linalg.norm(vec), limb))
    return out


def _canonical(v: np.ndarray) -> np.ndarray:
    """Unit vector with round-off components zeroed and its largest component positive."""
    v = np.where(np.abs(v) < 1e-12, 0.0, v)
    k = int(np.argmax(np.abs(v)))
    return v if v[k] > 0 else -v


def _components(graph: JointGraph) -> list[set[int]]:
    """Connected groups of bodies once ground and platform are removed."""
    skip = {0, graph.platform}
    adj: dict[int, set[int]] = {}
    for e in graph.edges:
        if e.parent not in skip and e.child not in skip:
            adj.setdefault(e.parent, set()).add(e.child)
            adj.setdefault(e.child, set()).add(e.parent)
        for b in (e.parent, e.child):
            if b not in skip:
                adj.setdefault(b, set())
    seen: set[int] = set()
    groups = []
    for start in sorted(adj):
        if start in seen:
            continue
        group, stack = set(), [start]
        while stack:
            b = stack.pop()
            if b in group:
                continue
            group.add(b)
            stack.extend(adj[b] - group)
        seen |= group
        groups.append(group)
    return groups


def _paths(edges: list[Edge], start: int, goal: int, limit: int = 64) -> list[list[tuple[Edge, int]]]:
    """Simple paths start -> goal as lists of (edge, +1 forward / -1 backward)."""
    out: list[list[tuple[Edge, int]]] = []

    def walk(node: int, visited: set[int], path: list[tuple[Edge, int]]) -> None:
        if len(out) >= limit:
            return
        if node == goal:
            out.append(list(path))
            return
        for e in edges:
            for a, b, sign in ((e.parent, e.child, 1), (e.child, e.parent, -1)):
                if a == node and b not in visited:
                    path.append((e, sign))
                    walk(b, visited | {b}, path)
                    path.pop()

    walk(start, {start}, [])
    return out


def screw_analysis(robot: Robot, q: np.ndarray) -> ScrewAnalysis:
    """Limb constraint wrenches, their union and the platform's twist space at q.

    A limb with several sub-chains from ground to platform (a parallelogram's two rods on one
    carriage) gives the platform the twists common to all its sub-chains with shared joints
    moving at one rate: T = P_1 x with (P_k - P_1) x = 0, P_k the k-th sub-chain's twist matrix
    over the limb's joint rates. The limb's constraint wrenches are the reciprocal of that space.
    """
    graph = joint_graph(robot, q)
    ee = robot.frame_id(robot.loops.end_effector if robot.loops is not None else robot.tool_frame)
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    E = data.oMf[ee].translation.copy()
    length = length_scale(robot, q)
    limbs: list[Limb] = []
    all_wrenches: list[Any] = []
    groups = _components(graph)
    direct = [e for e in graph.edges if {e.parent, e.child} == {0, graph.platform}]
    members = [(g, [e for e in graph.edges if (e.parent in g or e.child in g)]) for g in groups]
    members += [(set(), [e]) for e in direct]
    for _, edges in members:
        if not any(graph.platform in (e.parent, e.child) for e in edges) or not any(0 in (e.parent, e.child) for e in edges):
            continue  # a dangling branch (e.g. fingers): not a limb
        paths = _paths(edges, 0, graph.platform)
        dofs = sorted({d for e in edges for d in e.dofs})
        col = {d: i for i, d in enumerate(dofs)}
        P = []
        for path in paths:
            M = np.zeros((6, len(dofs)))
            for e, sign in path:
                for d in e.dofs:
                    M[:, col[d]] += sign * graph.twists[:, d]
            P.append(M)
        if len(P) > 1:
            N = _null(np.vstack([Pk - P[0] for Pk in P[1:]]), scale=np.abs(np.vstack(P)).max())
            T = _orth(P[0] @ N)
        else:
            T = _orth(P[0])
        W = _null(T.T, scale=1.0) if T.shape[1] else np.eye(6)
        name = f"limb {len(limbs) + 1}"
        wrenches = tuple(classify_wrenches(W, E, length, name))
        all_wrenches.extend(wrenches)
        limbs.append(Limb(name, tuple(e.name for e in edges), len(paths), T.shape[1], wrenches))
    Wall = np.array([w.vector for w in all_wrenches]).T if all_wrenches else np.zeros((6, 0))
    union = _orth(Wall)
    twists = _null(union.T, scale=1.0) if union.shape[1] else np.eye(6)
    freedoms, point_axes = classify_twists(twists, E, length)
    return ScrewAnalysis(tuple(limbs), union.shape[1], tuple(freedoms), tuple(point_axes), length)


def classify_twists(T: np.ndarray, point: np.ndarray, length: float,
                    rtol: float = TRANSLATION_RTOL) -> tuple[list[Freedom], list[np.ndarray]]:
    """Freedoms of a body from its twist space, and the directions its point `point` moves in.

    The twists are moved to `point` (v_E = v_O + w x E) and scaled to (v_E / L; w) so that both
    halves are rates of the same kind [rad/s]; in an orthonormal basis Q of that space, the SVD
    of the angular block Q_w = U S V^T orders the basis twists Q V by |w| (each has
    |v_E / L|^2 + |w|^2 = 1). Those with |w| <= rtol are translations along their v_E; the others
    are rotations, orthogonal to the translations, i.e. each is the rotation of its class (modulo
    the translations) that moves E least, whose axis passes nearest E.

    Args:
        T: 6 x k twists (v_O; w) spanning the space, independent columns [m/s; rad/s].
        point: the end-effector point E [m] (world).
        length: the model's length scale L [m].
        rtol: see TRANSLATION_RTOL.

    Returns:
        (freedoms, translations first; unit world directions the point moves in).
    """
    k = T.shape[1]
    if k == 0:
        return [], []
    w = T[3:]
    vE = T[:3] + np.cross(w.T, point).T
    U, _, _ = np.linalg.svd(np.vstack([vE / length, w]), full_matrices=False)
    Q = U[:, :k]
    _, sw, Vt = np.linalg.svd(Q[3:], full_matrices=True)
    sw = np.concatenate([sw, np.zeros(k - sw.size)])
    B = Q @ Vt.T  # basis twists ordered by |w| descending, scaled (v_E / L; w)
    trans = B[:, sw <= rtol]
    out: list[Freedom] = []
    if trans.shape[1]:
        Ut, _, _ = np.linalg.svd(trans[:3], full_matrices=False)
        out += [Freedom("translation", _canonical(t)) for t in Ut[:, : trans.shape[1]].T]
    for col in B[:, sw > rtol][:, ::-1].T:  # ascending |w|: after the translations, near ones first
        v, om = col[:3] * length, col[3:]
        n2 = float(om @ om)
        pitch = float(om @ v / n2)
        pitch = 0.0 if abs(pitch) <= rtol * length else pitch  # < 1e-6 L per radian: round-off
        out.append(Freedom("rotation", _canonical(om / np.sqrt(n2)), point + np.cross(om, v) / n2, pitch))
    Up, sp, _ = np.linalg.svd(Q[:3], full_matrices=False)
    moves = int(np.sum(sp > rtol))  # |v_E / L| > rtol for a unit scaled twist (|w| <= 1)
    return out, [_canonical(a) for a in Up[:, :moves].T]


# -- numeric mobility ----------------------------------------------------------------------------
@dataclass(frozen=True)
class NumericMobility:
    """nv - rank(K) from the loop-constraint Jacobian K, with the evidence for the rank."""

    nv: int
    constraints: int
    rank: int
    tolerance: float
    smallest_kept: float
    largest_dropped: float
    platform_freedoms: int
    locked_platform_freedoms: int
    serial: bool = False
    locked_position_freedoms: int = 0
    """Of the locked platform freedoms, those that move the end effector's origin (the others only
    turn the frame about it)."""

    @property
    def mobility(self) -> int:
        return self.nv - self.rank

    @property
    def idle(self) -> int:
        """Loop freedoms that move joints but not the platform (e.g. a rod spinning between S
        joints); 0 for a serial arm, whose surplus freedoms are `redundant`."""
        return 0 if self.serial else self.mobility - self.platform_freedoms

    @property
    def redundant(self) -> int:
        """A serial arm's joint freedoms beyond the tool's (self-motion; more at a singular pose)."""
        return self.mobility - self.platform_freedoms if self.serial else 0

    @property
    def gap(self) -> float:
        """smallest kept / largest dropped singular value (inf when nothing was dropped)."""
        return self.smallest_kept / self.largest_dropped if self.largest_dropped > 0 else float("inf")

    def as_dict(self) -> dict[str, Any]:
        return {"mobility": self.mobility, "nv": self.nv, "constraints": self.constraints, "rank": self.rank,
                "tolerance": self.tolerance, "smallest_kept": self.smallest_kept,
                "largest_dropped": self.largest_dropped, "gap": self.gap,
                "platform_freedoms": self.platform_freedoms, "idle": self.idle, "redundant": self.redundant,
                "locked_platform_freedoms": self.locked_platform_freedoms,
                "locked_position_freedoms": self.locked_position_freedoms}


def numeric_mobility(robot: Robot, q: np.ndarray, rtol: float = RANK_RTOL) -> NumericMobility:
    """Rank of the loop-constraint Jacobian at q, the platform's share of the null space, and the
    platform's freedom with the actuators locked (0 away from singularities)."""
    model = robot.model
    if robot.loops is not None:
        from kinematics.generic.closedloop import ClosedLoop

        cl = ClosedLoop(robot)
        _, K = cl.residual(q)
        actuated = cl.actuated_v
        ee = cl.ee
    else:
        K = np.zeros((0, model.nv))
        actuated = np.arange(model.nv)
        ee = robot.frame_id()
    s = np.linalg.svd(K, compute_uv=False) if K.size else np.zeros(0)
    rank = _rank(s, rtol)
    smallest = float(s[rank - 1]) if rank else 0.0
    dropped = float(s[rank]) if rank < s.size else 0.0
    N = _null(K, rtol)
    J = matrix(pin.computeFrameJacobian(model, model.createData(), q, ee, pin.LOCAL_WORLD_ALIGNED), model.nv)
    scale = max(float(np.abs(J).max()), 1e-300)
    platform = _rank(np.linalg.svd(J @ N, compute_uv=False), rtol) if N.size else 0
    lock = np.zeros((len(actuated), model.nv))
    lock[np.arange(len(actuated)), actuated] = 1.0
    KL = np.vstack([K / (s[0] if s.size and s[0] > 0 else 1.0), lock])
    NL = _null(KL, rtol)
    locked = locked_position = 0
    if NL.size:
        sl = np.linalg.svd(J @ NL, compute_uv=False)
        locked = int(np.sum(sl > rtol * scale))
        locked_position = int(np.sum(np.linalg.svd(J[:3] @ NL, compute_uv=False) > rtol * scale))
    return NumericMobility(model.nv, K.shape[0], rank, rtol, smallest, dropped, platform, locked, robot.loops is None,
                           locked_position)


# -- all three together --------------------------------------------------------------------------
@dataclass(frozen=True)
class MobilityReport:
    """The three analyses at one configuration, and what they say about each other."""

    grubler: GrublerCount
    numeric: NumericMobility
    screw: ScrewAnalysis
    notes: tuple[str, ...] = field(default=())

    def as_dict(self) -> dict[str, Any]:
        return {"grubler": self.grubler.as_dict(), "numeric": self.numeric.as_dict(),
                "screw": self.screw.as_dict(), "notes": list(self.notes)}


def analyse(robot: Robot, q: np.ndarray) -> MobilityReport:
    """Grübler–Kutzbach, numeric and screw mobility at q, with notes wherever they disagree."""
    g = grubler(robot, q)
    n = numeric_mobility(robot, q)
    s = screw_analysis(robot, q)
    notes = []
    if g.mobility != n.mobility:
        notes.append(
            f"Grübler-Kutzbach gives {g.mobility} (lambda = {g.lam}) but the constraint Jacobian has rank {n.rank}, "
            f"so the joints have {n.mobility} freedoms: the formula assumes independent constraints, but "
            f"{n.constraints - n.rank} of the {n.constraints} loop equations are redundant here "
            "(special geometry: parallel axes, a planar sub-loop, or a singular pose)")
    if n.idle > 0:
        notes.append(f"{n.idle} of the {n.mobility} joint freedoms are idle: they move joints but not the platform "
                     "(e.g. a rod spinning about its axis between two spherical joints)")
    if n.serial:
        generic = regular_configuration(robot).generic_rank
        lost = generic - n.platform_freedoms
        if lost > 0:
            notes.append(f"singular configuration: the tool's Jacobian has rank {n.platform_freedoms} here, "
                         f"{generic} at a regular pose of this arm; the freedoms reported are this pose's")
        if n.redundant > 0:
            why = [f"{n.mobility - generic} by design"] if n.mobility > generic else []
            why += [f"{lost} from the singularity"] if lost > 0 else []
            notes.append(f"{n.redundant} of the {n.mobility} joint freedoms are redundant: they move the joints "
                         f"without moving the tool ({', '.join(why)})")
    if s.translations + s.rotations != n.platform_freedoms:
        notes.append(f"screw theory finds {s.translations + s.rotations} platform freedoms but the constrained "
                     f"Jacobian {n.platform_freedoms}: the limbs' wrench systems are not a complete description here "
                     "(a singular pose, or constraints that only act at second order)")
    if n.locked_platform_freedoms > 0 and n.locked_position_freedoms == 0 and robot.loops is not None:
        from kinematics.generic.closedloop import ClosedLoop
        from kinematics.mechanisms.closed_loop import held_frames

        held = held_frames(ClosedLoop(robot), q)
        notes.append(f"with the actuators locked the end effector {robot.loops.end_effector!r} keeps "
                     f"{n.locked_platform_freedoms} freedom(s), all turning it about its own origin (its position "
                     "is held): a frame on a body the actuators do not hold (e.g. a rod free to spin about its own "
                     "axis), or a singular configuration (type II / direct-kinematic)"
                     + (f"; frames the actuators hold here: {', '.join(held)}" if held else ""))
    elif n.locked_platform_freedoms > 0:
        notes.append(f"with the actuators locked the platform keeps {n.locked_platform_freedoms} freedom(s): "
                     "a singular configuration (type II / direct-kinematic)")
    if np.isfinite(n.gap) and n.gap < 1e3:
        notes.append(f"the constraint Jacobian's singular values have no clear gap at the rank cut "
                     f"({n.smallest_kept:.3g} kept vs {n.largest_dropped:.3g} dropped): near a singularity")
    return MobilityReport(g, n, s, tuple(notes))
