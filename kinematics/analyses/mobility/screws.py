"""Screw theory: each limb's constraint wrenches, their union and the platform's reciprocal twists,
classified by their geometry (pure translations and couples, rotations and forces on lines)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import pinocchio as pin

from kinematics.generic.serial import length_scale
from kinematics.model.robot import Robot

from .graph import components, joint_graph, simple_paths
from .linalg import null, orth

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
        out.append(Wrench("couple", canonical(m / np.linalg.norm(m)), None, vec / np.linalg.norm(vec), limb))
    for col in B[:, sf > rtol][:, ::-1].T:
        fo, m = col[:3], col[3:] * length
        nf2 = float(fo @ fo)
        vec = np.concatenate([fo, m + np.cross(point, fo)])
        out.append(Wrench("force", canonical(fo / np.sqrt(nf2)), point + np.cross(fo, m) / nf2,
                          vec / np.linalg.norm(vec), limb))
    return out


def canonical(v: np.ndarray) -> np.ndarray:
    """Unit vector with round-off components zeroed and its largest component positive."""
    v = np.where(np.abs(v) < 1e-12, 0.0, v)
    k = int(np.argmax(np.abs(v)))
    return v if v[k] > 0 else -v


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
    groups = components(graph)
    direct = [e for e in graph.edges if {e.parent, e.child} == {0, graph.platform}]
    members = [(g, [e for e in graph.edges if (e.parent in g or e.child in g)]) for g in groups]
    members += [(set(), [e]) for e in direct]
    for _, edges in members:
        if not any(graph.platform in (e.parent, e.child) for e in edges) or not any(0 in (e.parent, e.child) for e in edges):
            continue  # a dangling branch (e.g. fingers): not a limb
        paths = simple_paths(edges, 0, graph.platform)
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
            N = null(np.vstack([Pk - P[0] for Pk in P[1:]]), scale=np.abs(np.vstack(P)).max())
            T = orth(P[0] @ N)
        else:
            T = orth(P[0])
        W = null(T.T, scale=1.0) if T.shape[1] else np.eye(6)
        name = f"limb {len(limbs) + 1}"
        wrenches = tuple(classify_wrenches(W, E, length, name))
        all_wrenches.extend(wrenches)
        limbs.append(Limb(name, tuple(e.name for e in edges), len(paths), T.shape[1], wrenches))
    Wall = np.array([w.vector for w in all_wrenches]).T if all_wrenches else np.zeros((6, 0))
    union = orth(Wall)
    twists = null(union.T, scale=1.0) if union.shape[1] else np.eye(6)
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
        out += [Freedom("translation", canonical(t)) for t in Ut[:, : trans.shape[1]].T]
    for col in B[:, sw > rtol][:, ::-1].T:  # ascending |w|: after the translations, near ones first
        v, om = col[:3] * length, col[3:]
        n2 = float(om @ om)
        pitch = float(om @ v / n2)
        pitch = 0.0 if abs(pitch) <= rtol * length else pitch  # < 1e-6 L per radian: round-off
        out.append(Freedom("rotation", canonical(om / np.sqrt(n2)), point + np.cross(om, v) / n2, pitch))
    Up, sp, _ = np.linalg.svd(Q[:3], full_matrices=False)
    moves = int(np.sum(sp > rtol))  # |v_E / L| > rtol for a unit scaled twist (|w| <= 1)
    return out, [canonical(a) for a in Up[:, :moves].T]

