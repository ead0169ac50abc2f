"""The closed-form steps both three-limb families take the same way: checking inputs, the real
root of a limb's IK discriminant, assembling the two roots of each limb into the 8 working modes,
and the velocity matrices J_x, J_q, J = J_q^-1 J_x with their singularity measures."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from kinematics.errors import InvalidInputError, UnknownChoiceError
from kinematics.inputs import finite_vectors
from kinematics.mechanisms.base import SINGULAR_TOL
from kinematics.mechanisms.three_limb.closed_form import BOUNDARY_TOL, MODES, mode_index

LIMITS = ("all", "actuators")
"""Which limits apply: every limit (actuators and passive joints), or the actuators only."""


def check_limits(limits: str) -> bool:
    """True when the passive limits apply; raises UnknownChoiceError for anything but LIMITS."""
    if limits not in LIMITS:
        raise UnknownChoiceError(limits, LIMITS)
    return limits == "all"


MODE_ROOTS = np.array([[0 if c == "+" else 1 for c in m] for m in MODES])  # (8, 3)
"""Per working mode (row, order of MODES) and limb: the IK root it takes, 0 = "+", 1 = "-"."""


def points(p: np.ndarray, name: str = "position") -> np.ndarray:
    """Platform positions as floats of shape S + (3,); InvalidInputError if not, or not finite."""
    return finite_vectors(p, 3, name)


def one(v: np.ndarray, name: str) -> np.ndarray:
    """`v` (from `points` or `actuators`) if it is a single 3-vector, for a single-pose report;
    InvalidInputError for a batch (the batched maps take those)."""
    if v.shape != (3,):
        raise InvalidInputError(name, f"expected one 3-vector, got shape {v.shape} (a batch goes to the batched maps)")
    return v


def actuators(q: np.ndarray, what: str) -> np.ndarray:
    """Actuator values (`what`: "values", "angles") as floats of shape S + (3,); raises if not."""
    return finite_vectors(q, 3, "q", f"actuator {what}")


def real_root(disc: np.ndarray, length: float) -> tuple[np.ndarray, np.ndarray]:
    """(reach, sqrt(disc)) of an IK discriminant disc [m^2]: down to -BOUNDARY_TOL length^2 it
    counts as zero (on a reach boundary rounding leaves +/-1e-17); NaN where the limb cannot reach."""
    reach = disc >= -BOUNDARY_TOL * length**2
    return reach, np.sqrt(np.where(reach, np.maximum(disc, 0.0), np.nan))


@dataclass(frozen=True)
class LimbRoots:
    """Per-limb IK for points of shape S + (3,); root axis: 0 = "+", 1 = "-". A family's
    `LimbSolutions` adds what tells why a limb does not reach.

    Attributes:
        q: S + (3, 2) actuator values [m or rad] (NaN where the limb cannot reach).
        n: S + (3, 2, 3) unit rod directions, from the rod's actuated end to the platform.
        reach: S + (3,) the limb reaches the point.
    """

    q: np.ndarray
    n: np.ndarray
    reach: np.ndarray


class IKResult(NamedTuple):
    """IK over all 8 working modes for points of shape S + (3,).

    Attributes:
        q: S + (8, 3) actuator values per mode (order of MODES) [m or rad]; NaN where a limb
            cannot reach.
        reachable: S + (8,) every limb reaches in that mode (limits ignored).
        within_limits: S + (8,) reachable and every limit checked holds.
        limbs: the family's per-limb solutions behind them (q, n, reach, ...).
        limb_ok: S + (3, 2) per limb and root: reaches and respects its limits.
    """

    q: np.ndarray
    reachable: np.ndarray
    within_limits: np.ndarray
    limbs: Any
    limb_ok: np.ndarray


def by_mode(limbs: LimbRoots, actuator_ok: np.ndarray, passive_ok: np.ndarray, passive: bool) -> IKResult:
    """Assemble per-limb solutions `limbs` into the 8 working modes; a root is within the limits where its limb reaches, `actuator_ok` holds and,
    if `passive`, `passive_ok` holds (both S + (3, 2))."""
    ok = limbs.reach[..., None] & actuator_ok
    if passive:
        ok &= passive_ok
    idx = np.arange(3)
    all_reach = np.all(limbs.reach, axis=-1)[..., None]
    reachable = np.broadcast_to(all_reach, all_reach.shape[:-1] + (len(MODES),))
    within = np.all(ok[..., idx, MODE_ROOTS], axis=-1)
    return IKResult(limbs.q[..., idx, MODE_ROOTS], reachable, within, limbs, ok)


def mode_roots(reach: np.ndarray, position: np.ndarray, mode: str) -> np.ndarray:
    """The root index (0 = "+", 1 = "-") of each limb in working mode `mode` at one position
    whose per-limb `reach` (3,) is given; InvalidInputError naming the limbs that cannot reach."""
    m = mode_index(mode)
    if not reach.all():
        bad = [str(i + 1) for i in range(3) if not reach[i]]
        raise InvalidInputError("position", f"limb(s) {', '.join(bad)} cannot reach {position.tolist()}")
    return MODE_ROOTS[m]


class Jacobians(NamedTuple):
    """Velocity matrices at positions S + (3,) with actuator values S + (3,).

    Attributes:
        Jx: S + (3, 3), rows r_i: each rod from its actuated end to the platform [m].
        Jq: S + (3,), the diagonal r_i . (velocity of the rod's actuated end per unit actuator
            rate) [m or m^2/rad].
        J: S + (3, 3), J_q^-1 J_x: qdot = J pdot (inf rows where J_q_ii = 0).
        iota_I, iota_II: S, the scale-free singularity measures in [0, 1].
    """

    Jx: np.ndarray
    Jq: np.ndarray
    J: np.ndarray
    iota_I: np.ndarray
    iota_II: np.ndarray


def unit_rods(r: np.ndarray) -> np.ndarray:
    """n_i = r_i / |r_i| for rod vectors S + (3, 3)."""
    return r / np.linalg.norm(r, axis=-1, keepdims=True)


def jacobians_of(r: np.ndarray, jq: np.ndarray, n: np.ndarray, cos_I: np.ndarray) -> Jacobians:
    """Jacobians from the rod vectors r, S + (3, 3), the diagonal jq, S + (3,), their directions
    n = `unit_rods(r)` and the cosines `cos_I`, S + (3,), between each rod and its actuated end's
    velocity: iota_I = min |cos_I|, iota_II = |det[n_1; n_2; n_3]|."""
    with np.errstate(divide="ignore", invalid="ignore"):
        J = r / jq[..., None]
    return Jacobians(r, jq, J, np.min(np.abs(cos_I), axis=-1), np.abs(np.linalg.det(n)))


def inverse_of(jac: Jacobians) -> np.ndarray:
    """J^-1 = J_x^-1 J_q: pdot = J^-1 qdot (InvalidInputError where J_x is singular, type II)."""
    if np.any(jac.iota_II <= SINGULAR_TOL):
        raise InvalidInputError("position", "J_x is singular (type II): J has no inverse here")
    return np.linalg.solve(jac.Jx, np.eye(3) * jac.Jq[..., None, :])


def angle_text(x: float) -> str:
    """An angle for a message: radians and degrees."""
    return f"{x:.6g} rad ({math.degrees(x):.4g} deg)"
