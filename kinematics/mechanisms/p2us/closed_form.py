"""Closed-form kinematics of the 3-[P2(US)] translational parallel robot (paper B), vectorised.

Frame and sign convention (the paper's eqs. 8 and 11-15 disagree; we follow 11-18):

* world z up, origin at the centre of the fixed (upper) base; the platform hangs below (z < 0);
* limb i: e_i = (cos a_i, sin a_i, 0), t_i = (-sin a_i, cos a_i, 0), base point A_i = b e_i;
* the actuator slides **inward and downward**: w_i = (-cos b cos a_i, -cos b sin a_i, -sin b)
  (b = beta, the rail's angle below the horizontal), carriage B_i = A_i + q_i w_i, 0.1 <= q <= 0.6 m;
* the platform point of limb i is C_i = p + d e_i, and the rod constraint is |C_i - B_i| = L.

With v_i = p + (d - b) e_i:  |v_i - q_i w_i|^2 = L^2, so
q_i = A_i +/- sqrt(A_i^2 - G_i), A_i = v_i . w_i, G_i = |v_i|^2 - L^2 (paper eq. 18, with eq. 16's
A_i taken along w_i). Root "+" is the larger q (carriage further down the rail), "-" the smaller;
a working mode is one root per limb, labelled e.g. "+-+" (limbs 1, 2, 3).

Universal-joint angles of rod direction n = (C_i - B_i)/L (both rods of a parallelogram share it).
The URDF's joint coordinates: u_theta turns the rod about the tangential axis -t_i, down from the
inward horizontal -e_i; u_phi swings it out of the limb's vertical plane towards -t_i. With
eps = theta_zero + u_theta (the rod's elevation below the inward horizontal):

    n = cos(phi) [cos(eps) (-e_i) - sin(eps) z] - sin(phi) t_i

The paper's limits (eq. 30) do not say which angles they bound, so the reading is a model choice
recorded in the loop sidecar (`THETA_CONVENTIONS`, `PHI_CONVENTIONS`) and used by every check:

* theta "elevation": theta = u_theta, the joint coordinate above (its limits are the URDF's);
* theta "rod-rail": theta = arccos(n . w_i) in [0, pi], the angle between rod and rail (the
  direction of increasing q); a function of both joint coordinates, so its range lives in the
  sidecar and the URDF joint is left unlimited;
* phi "tangential": phi = arcsin(-n . t_i), the rod's angle out of the plane normal to the
  tangential axis (the U joint's first axis), i.e. the u_phi coordinate.

Velocity (eqs. 25-28): f_i = (|v_i - q_i w_i|^2 - L^2)/2 = 0 gives J_x pdot = J_q qdot with
J_x = [r_i^T] (r_i = C_i - B_i) and J_q = diag(r_i . w_i); J = J_q^-1 J_x (qdot = J pdot).

Singularity types (Gosselin & Angeles 1990; the paper's verbal labels are swapped): type I when
J_q is singular (a rod perpendicular to its rail), type II when J_x is (the three rods parallel to
one plane), type III both. Scale-free measures in [0, 1]:
iota_I = min_i |n_i . w_i| (cosine of rod-rail angle), iota_II = |det[n_1; n_2; n_3]|.
A pose is classified singular when a measure is <= SINGULAR_TOL.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from kinematics.errors import InvalidDesignError, InvalidInputError
from kinematics.mechanisms.base import SINGULAR_TOL as SINGULAR_TOL
from kinematics.mechanisms.base import SINGULARITY_TYPES as SINGULARITY_TYPES
from kinematics.mechanisms.base import classify as classify
from kinematics.mechanisms.three_limb import modes
from kinematics.mechanisms.three_limb.closed_form import ACTUATOR_TOL
from kinematics.mechanisms.three_limb.closed_form import ASSEMBLY_MODES as ASSEMBLY_MODES
from kinematics.mechanisms.three_limb.closed_form import BOUNDARY_TOL as BOUNDARY_TOL
from kinematics.mechanisms.three_limb.closed_form import MODES as MODES
from kinematics.mechanisms.three_limb.closed_form import FKResult as FKResult
from kinematics.mechanisms.three_limb.closed_form import intersect_spheres as intersect_spheres
from kinematics.mechanisms.three_limb.closed_form import mode_index as mode_index
from kinematics.mechanisms.three_limb.modes import IKResult as IKResult
from kinematics.mechanisms.three_limb.modes import Jacobians as Jacobians
from kinematics.mechanisms.three_limb.params import LimbDesign, check_pair

THETA_CONVENTIONS: tuple[str, ...] = ("elevation", "rod-rail")
"""Readings of the first universal-joint angle theta (see the module docstring)."""

PHI_CONVENTIONS: tuple[str, ...] = ("tangential",)
"""Readings of the second universal-joint angle phi (see the module docstring)."""


@dataclass(frozen=True)
class P2USParams(LimbDesign):
    """Design of a 3-[P2(US)] robot; defaults are paper B's Table 2 and eq. 30.

    Attributes:
        b: base radius [m] (A_i = b e_i).
        d: platform radius [m] (C_i = p + d e_i).
        L: rod length [m].
        beta: rail angle below the horizontal [rad].
        alpha: limb angles a_i [rad].
        stroke: actuator range (q_min, q_max) [m].
        theta_limits: first universal-joint angle range [rad].
        phi_limits: second universal-joint angle range [rad], within (-pi/2, pi/2).
        theta_zero: rod elevation below the inward horizontal at u_theta = 0 [rad].
        rod_spacing: distance between the two rods of a parallelogram [m] (not in the paper).
        theta_convention: what theta_limits bound, one of THETA_CONVENTIONS.
        phi_convention: what phi_limits bound, one of PHI_CONVENTIONS.
    """

    b: float = 0.325
    d: float = 0.028
    L: float = 0.340
    beta: float = math.radians(40)
    alpha: tuple[float, float, float] = (0.0, math.radians(120), math.radians(240))
    stroke: tuple[float, float] = (0.1, 0.6)
    theta_limits: tuple[float, float] = (math.radians(-10), math.radians(100))
    phi_limits: tuple[float, float] = (math.radians(-70), math.radians(70))
    theta_zero: float = 0.0
    rod_spacing: float = 0.05
    theta_convention: str = "elevation"
    phi_convention: str = "tangential"

    def __post_init__(self) -> None:
        from kinematics.errors import UnknownChoiceError

        if self.theta_convention not in THETA_CONVENTIONS:
            raise UnknownChoiceError(self.theta_convention, THETA_CONVENTIONS)
        if self.phi_convention not in PHI_CONVENTIONS:
            raise UnknownChoiceError(self.phi_convention, PHI_CONVENTIONS)
        self.check_common(("b", "d", "L", "rod_spacing"), ("beta", "theta_zero"))
        self._check_design()
        check_pair("stroke", self.stroke)
        check_pair("theta_limits", self.theta_limits)
        check_pair("phi_limits", self.phi_limits)
        if not (-math.pi / 2 < self.phi_limits[0] and self.phi_limits[1] < math.pi / 2):
            raise InvalidInputError("phi_limits", "must lie within (-90, 90) degrees")
        if self.theta_limits[1] - self.theta_limits[0] >= 2 * math.pi:
            raise InvalidInputError("theta_limits", "must span less than 360 degrees")

    def _check_design(self) -> None:
        """Reject degenerate geometry (InvalidDesignError): d >= b, beta outside [0, 90] degrees
        (coincident limbs: `check_common`)."""
        if self.d >= self.b:
            raise InvalidDesignError("d", self.d, f"the platform radius d must be smaller than the base "
                                     f"radius b = {self.b:g} m (only b - d > 0 is a working design)")
        if not 0.0 <= self.beta <= math.pi / 2:
            raise InvalidDesignError("beta", math.degrees(self.beta), "the rail angle below the horizontal "
                                     "must be within [0, 90] degrees")

    # Derived geometry, shape (3, 3): row i belongs to limb i (e, t: `LimbDesign`).
    @functools.cached_property
    def w(self) -> np.ndarray:
        """Unit actuator directions (inward, down)."""
        cb, sb = math.cos(self.beta), math.sin(self.beta)
        return np.concatenate([-cb * self.e[:, :2], np.full((3, 1), -sb)], axis=-1)

    @functools.cached_property
    def base_points(self) -> np.ndarray:
        """A_i = b e_i [m]."""
        return self.b * self.e

    @property
    def theta_joint_centre(self) -> float:
        """The u_theta coordinate [rad] at the middle of the rods' allowed swing in the limb plane:
        mid-range for "elevation"; for "rod-rail" the rod along its rail (eps = beta), the middle
        of the working branch between the two rod-perpendicular-to-rail (type I) elevations."""
        if self.theta_convention == "rod-rail":
            return self.beta - self.theta_zero
        return 0.5 * (self.theta_limits[0] + self.theta_limits[1])


# -- inverse kinematics ----------------------------------------------------------------------
@dataclass(frozen=True)
class LimbSolutions(modes.LimbRoots):
    """Per-limb IK (`LimbRoots`): q the carriage positions [m], n the rod directions
    (C_i - B_i)/L, reach where the discriminant >= -BOUNDARY_TOL L^2; and

    Attributes:
        axis_distance: S + (3,) distance of C_i from the rail's axis [m] (reach iff <= L).
    """

    axis_distance: np.ndarray


def limb_ik(params: P2USParams, p: np.ndarray) -> LimbSolutions:
    """Both carriage positions q = A_i +/- sqrt(A_i^2 - G_i) [m] of every limb (paper eq. 18) and
    the rod directions they give, at every platform position p [m]."""
    v = modes.points(p)[..., None, :] + (params.d - params.b) * params.e  # S + (3, 3)
    A = np.einsum("...ij,ij->...i", v, params.w)
    vv = np.einsum("...ij,...ij->...i", v, v)
    disc = A * A - (vv - params.L**2)
    reach, root = modes.real_root(disc, params.L)
    q = np.stack([A + root, A - root], axis=-1)  # S + (3, 2)
    n = (v[..., None, :] - q[..., None] * params.w[:, None, :]) / params.L
    dist = np.sqrt(np.maximum(vv - A * A, 0.0))
    return LimbSolutions(q, n, reach, dist)


def passive_angles(params: P2USParams, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Universal-joint angles (theta, phi) [rad] of unit rod directions n, shape S + (3, [2,] 3).

    The limb axis of `n` is the third-from-last when roots are present, else the second-from-last.
    """
    e, t = _limb_axes(params, n)
    ne = np.sum(n * e, axis=-1)
    nt = np.sum(n * t, axis=-1)
    nz = n[..., 2]
    phi = np.arcsin(np.clip(-nt, -1.0, 1.0))
    theta = np.arctan2(-nz, -ne) - params.theta_zero
    centre = params.theta_joint_centre
    theta = (theta - centre + math.pi) % (2 * math.pi) + centre - math.pi  # within pi of the centre
    return theta, phi


def limit_angles(params: P2USParams, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(theta, phi) [rad] as the design's conventions read them, for unit rod directions n (shapes
    as `passive_angles`): the angles its theta_limits and phi_limits bound."""
    theta, phi = passive_angles(params, n)
    if params.theta_convention == "rod-rail":
        theta = np.arccos(np.clip(np.sum(n * _limb_rails(params, n), axis=-1), -1.0, 1.0))
    return theta, phi


def _limb_axes(params: P2USParams, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """e_i, t_i broadcastable against n (limb axis at -3 with a root axis, else -2)."""
    if n.ndim >= 3 and n.shape[-3:-1] == (3, 2):
        return params.e[:, None, :], params.t[:, None, :]
    return params.e, params.t


def _limb_rails(params: P2USParams, n: np.ndarray) -> np.ndarray:
    """w_i broadcastable against n (as `_limb_axes`)."""
    return params.w[:, None, :] if n.ndim >= 3 and n.shape[-3:-1] == (3, 2) else params.w


def rod_rail_bounds(params: P2USParams) -> tuple[bool, float, float]:
    """(rod-rail convention?, c_lo, c_hi): theta = arccos(n.w) lies in theta_limits iff
    c_hi <= n.w <= c_lo, c = cos of the limit clipped to [0, pi]. A limit that cannot bind (lower
    <= 0, upper >= pi) becomes 2 / -2, so the slack stays finite and positive."""
    lo, hi = params.theta_limits
    c_lo = math.cos(lo) if lo > 0 else 2.0
    c_hi = math.cos(hi) if hi < math.pi else -2.0
    return params.theta_convention == "rod-rail", c_lo, c_hi


def angle_bounds(params: P2USParams) -> tuple[np.ndarray, np.ndarray, bool, float, float]:
    """The elevation-convention theta arc as trig-free tests: (direction of its lower end,
    direction of its upper end, the arc is at most 180 degrees, sin phi_min, sin phi_max)."""
    lo = params.theta_zero + params.theta_limits[0]
    hi = params.theta_zero + params.theta_limits[1]
    narrow = hi - lo <= math.pi
    return np.array([math.cos(lo), math.sin(lo)]), np.array([math.cos(hi), math.sin(hi)]), narrow, \
        math.sin(params.phi_limits[0]), math.sin(params.phi_limits[1])


def passive_limits_ok(params: P2USParams, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(theta within limits, phi within limits) for unit rod directions n, without trigonometry.

    phi in [phi_lo, phi_hi] iff -n.t in [sin phi_lo, sin phi_hi] (|phi| < 90 deg). The elevation
    vector (-n.e, -n.z) = cos(phi) (cos eps, sin eps) lies in the arc [eps_lo, eps_hi] iff it is
    on the inner side of both bounding directions (arcs up to 180 degrees; a wider arc is the
    complement of a narrower one).
    """
    e, t = _limb_axes(params, n)
    ex = -np.sum(n * e, axis=-1)
    ez = -n[..., 2]
    sphi = -np.sum(n * t, axis=-1)
    d_lo, d_hi, narrow, s_lo, s_hi = angle_bounds(params)
    rod_rail, c_lo, c_hi = rod_rail_bounds(params)
    if rod_rail:  # cos(theta) = n.w within [c_hi, c_lo]
        nw = np.sum(n * _limb_rails(params, n), axis=-1)
        theta_ok = (nw >= c_hi) & (nw <= c_lo)
    else:
        after_lo = d_lo[0] * ez - d_lo[1] * ex  # cross(d_lo, u) >= 0
        before_hi = ex * d_hi[1] - ez * d_hi[0]  # cross(u, d_hi) >= 0
        theta_ok = (after_lo >= 0) & (before_hi >= 0) if narrow else (after_lo >= 0) | (before_hi >= 0)
    phi_ok = (sphi >= s_lo) & (sphi <= s_hi)
    return theta_ok, phi_ok


def limb_limits(params: P2USParams, limbs: LimbSolutions) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per limb and root: (stroke ok, theta ok, phi ok), each S + (3, 2)."""
    with np.errstate(invalid="ignore"):
        stroke_ok = (limbs.q >= params.stroke[0] - ACTUATOR_TOL) & (limbs.q <= params.stroke[1] + ACTUATOR_TOL)
    theta_ok, phi_ok = passive_limits_ok(params, limbs.n)
    return stroke_ok, theta_ok, phi_ok


def ik(params: P2USParams, p: np.ndarray, *, limits: bool = True) -> IKResult:
    """Inverse kinematics in all 8 working modes at every position p [m].

    Args:
        limits: check the passive (universal-joint) limits too; False checks strokes only.
    """
    limbs = limb_ik(params, p)
    stroke_ok, theta_ok, phi_ok = limb_limits(params, limbs)
    return modes.by_mode(limbs, stroke_ok, theta_ok & phi_ok, limits)


# -- forward kinematics ----------------------------------------------------------------------
def sphere_centres(params: P2USParams, q: np.ndarray) -> np.ndarray:
    """c_i = B_i - d e_i: the platform centre lies at distance L from each, S + (3, 3)."""
    q = modes.actuators(q, "values")
    return params.base_points + q[..., None] * params.w - params.d * params.e


def fk(params: P2USParams, q: np.ndarray) -> FKResult:
    """Forward kinematics (paper eqs. 19-21): intersect three spheres of radius L around the
    centres c_i = B_i - d e_i (`intersect_spheres`)."""
    return intersect_spheres(sphere_centres(params, q), params.L)


# -- velocity and singularities ---------------------------------------------------------------
def rod_vectors(params: P2USParams, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """r_i = C_i - B_i [m], shape S + (3, 3)."""
    p = modes.points(p)
    q = modes.actuators(q, "values")
    return p[..., None, :] + params.d * params.e - params.base_points - q[..., None] * params.w


def jacobians(params: P2USParams, p: np.ndarray, q: np.ndarray) -> Jacobians:
    """J_x, J_q, J = J_q^-1 J_x and the singularity measures at (p, q)."""
    r = rod_vectors(params, p, q)
    n = modes.unit_rods(r)
    return modes.jacobians_of(r, np.einsum("...ij,ij->...i", r, params.w), n, np.einsum("...ij,ij->...i", n, params.w))


def violations(params: P2USParams, q: np.ndarray, n: np.ndarray) -> list[str]:
    """Readable list of the limits a single pose breaks.

    Args:
        q: (3,) actuator values [m].
        n: (3, 3) unit rod directions, row i for limb i.
    """
    deg = modes.angle_text
    theta, phi = limit_angles(params, n)
    theta_ok, phi_ok = passive_limits_ok(params, n)
    theta_name = "theta (rod-rail angle)" if params.theta_convention == "rod-rail" else "theta"
    out = []
    for i in range(3):
        lim = f"limb {i + 1}: "
        if q[i] < params.stroke[0] - ACTUATOR_TOL:
            out.append(lim + f"q = {q[i]:.6g} m below the stroke's {params.stroke[0]:g} m")
        elif q[i] > params.stroke[1] + ACTUATOR_TOL:
            out.append(lim + f"q = {q[i]:.6g} m above the stroke's {params.stroke[1]:g} m")
        if not theta_ok[i]:
            lo, hi = params.theta_limits
            out.append(lim + f"{theta_name} = {deg(theta[i])} outside [{deg(lo)}, {deg(hi)}]")
        if not phi_ok[i]:
            lo, hi = params.phi_limits
            out.append(lim + f"phi = {deg(phi[i])} outside [{deg(lo)}, {deg(hi)}]")
    return out


def jacobian_inverse(params: P2USParams, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """J^-1 = J_x^-1 J_q: pdot = J^-1 qdot (raises where J_x is singular)."""
    return modes.inverse_of(jacobians(params, p, q))
