"""Closed-form kinematics of Clavel's 3-RUU Delta robot, vectorised.

Frame and sign convention (docs/delta.md has the figure):

* world z up, origin at the centre of the fixed base; the platform hangs below (z < 0);
* limb i: e_i = (cos a_i, sin a_i, 0), t_i = (-sin a_i, cos a_i, 0); the actuator axis is the
  line through A_i = R e_i along t_i (R: base radius, centre to actuator axis);
* in-plane directions of limb i: d_i(eps) = cos(eps) e_i - sin(eps) z (eps = 0 outward
  horizontal, eps = 90 deg straight down);
* the upper arm points along d_i(theta_i): the elbow is E_i = A_i + l_a d_i(theta_i), theta
  below the horizontal, theta = 0 horizontal pointing outward;
* the platform point of limb i is C_i = p + r e_i (r: platform radius) and the forearm (a
  parallelogram of two rods of length l_b) keeps |C_i - E_i| = l_b.

IK. With v_i = p + (r - R) e_i = C_i - A_i, x = v.e_i, h = v.z, y = v.t_i:
|v - l_a d(theta)|^2 = l_b^2 gives x cos(theta) - h sin(theta) = K,
K = (|v|^2 + l_a^2 - l_b^2) / (2 l_a). With rho = hypot(x, h), phi0 = atan2(-h, x):
theta = phi0 +/- atan2(sqrt(rho^2 - K^2), K). Root "+" turns the arm from the in-plane line
actuator axis -> platform joint towards increasing theta ((E - A) x (C - A) . t_i <= 0), "-"
the other way (below the base, "-" is the usual elbow-out Delta); a working mode is one root per
limb, e.g. "--+" (limbs 1, 2, 3). The limb reaches iff |K| <= rho. Angles are reported within
pi of the middle of the actuator range.

FK. The platform centre is at distance l_b from c_i = E_i - r e_i: three spheres,
`parallel.intersect_spheres`, assembly modes "below"/"above" the centres' plane.

Velocity. f_i = (|C_i - E_i|^2 - l_b^2)/2 = 0 gives J_x pdot = J_q thetadot, J_x = [r_i^T]
(r_i = C_i - E_i [m]), J_q = diag(r_i . b_i) [m^2/rad], b_i = dE_i/dtheta_i = l_a d_i(theta_i + 90
deg) [m/rad]; J = J_q^-1 J_x (thetadot = J pdot, rad/m).

Singularities (Gosselin & Angeles 1990). Type I: J_q singular, a forearm perpendicular to its
elbow's velocity (it lies in the plane of its upper arm and the actuator axis: arm and forearm
stretched or folded as seen along the actuator axis). Type II: J_x singular, the three forearm
directions parallel to one plane. Type III: both. Scale-free measures in [0, 1]:
iota_I = min_i |n_i . b^_i|, iota_II = |det[n_1; n_2; n_3]| (n_i = r_i / l_b, b^_i = b_i / l_a).

Ball-joint cones. Every rod ends in a ball joint at the elbow and at the platform; each allows
the rod within a cone of half-angle `cone` about its socket axis. Elbow sockets turn with the
upper arm: s_E,i = d_i(theta_i + elbow_socket); platform sockets are fixed on the translating
platform: s_P,i = sin(platform_socket) e_i + cos(platform_socket) z (up, tilted outward). With
n_i the rod direction from elbow to platform: n_i . s_E,i >= cos(cone), -n_i . s_P,i >= cos(cone).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from kinematics.errors import InvalidDesignError
from kinematics.mechanisms.base import SINGULAR_TOL, SINGULARITY_TYPES, classify
from kinematics.mechanisms.three_limb import modes
from kinematics.mechanisms.three_limb.closed_form import (
    ACTUATOR_TOL,
    ASSEMBLY_MODES,
    MODES,
    FKResult,
    intersect_spheres,
    mode_index,
)
from kinematics.mechanisms.three_limb.modes import IKResult, Jacobians
from kinematics.mechanisms.three_limb.params import LimbDesign, check_pair

__all__ = [
    "ASSEMBLY_MODES", "MECHANISM", "MODES", "SINGULARITY_TYPES", "SINGULAR_TOL", "DeltaParams", "IKResult",
    "Jacobians", "LimbSolutions", "classify", "fk", "ik", "jacobians", "limb_ik", "limb_reasons", "mode_index",
    "passive_angles", "rod_vectors", "violations",
]

MECHANISM = "3-RUU Delta"
"""The sidecar's `mechanism:` value that enables these closed forms."""


@dataclass(frozen=True)
class DeltaParams(LimbDesign):
    """Design of a Delta robot; the defaults are the toolkit's built-in `delta`.

    Attributes:
        R: base radius [m], centre to actuator axis.
        r: platform radius [m], centre to the forearm's platform joints.
        la: upper-arm length [m], actuator axis to elbow.
        lb: forearm (parallelogram rod) length [m].
        alpha: limb angles a_i [rad].
        theta_limits: actuator range [rad] below the horizontal (0 horizontal outward).
        cone: half-angle of every ball joint's cone [rad], in (0, 90) deg.
        elbow_socket: angle of the elbow sockets' axis below the upper arm, in its plane [rad].
        platform_socket: outward tilt of the platform sockets' axis from the vertical [rad].
        rod_spacing: distance between the two rods of a parallelogram [m].
    """

    R: float = 0.20
    r: float = 0.05
    la: float = 0.30
    lb: float = 0.80
    alpha: tuple[float, float, float] = (0.0, math.radians(120), math.radians(240))
    theta_limits: tuple[float, float] = (math.radians(-40), math.radians(90))
    cone: float = math.radians(45)
    elbow_socket: float = math.radians(90)
    platform_socket: float = math.radians(20)
    rod_spacing: float = 0.08

    def __post_init__(self) -> None:
        self.check_common(("R", "r", "la", "lb", "rod_spacing"), ("cone", "elbow_socket", "platform_socket"))
        check_pair("theta_limits", self.theta_limits)
        self._check_design()

    def _check_design(self) -> None:
        """Reject degenerate geometry (InvalidDesignError carrying parameter, value, reason;
        coincident limbs: `check_common`)."""
        # Opposite limbs (180 deg apart) have parallel actuator axes: fine. All three axes
        # parallel needs all three angles equal mod 180, which with distinct angles mod 360 means
        # two coincide, refused by `check_common`.
        lo, hi = self.theta_limits
        if not (-math.pi < lo and hi < math.pi):
            raise InvalidDesignError("theta_limits", [math.degrees(lo), math.degrees(hi)],
                                     "the actuator range must lie within (-180, 180) degrees")
        if not 0.0 < self.cone < math.pi / 2:
            raise InvalidDesignError("cone", math.degrees(self.cone), "the ball joints' cone half-angle must be "
                                     "within (0, 90) degrees")
        if not 0.0 <= self.platform_socket < math.pi / 2:
            raise InvalidDesignError("platform_socket", math.degrees(self.platform_socket),
                                     "the platform sockets' outward tilt must be within [0, 90) degrees")
        if not -math.pi < self.elbow_socket <= math.pi:
            raise InvalidDesignError("elbow_socket", math.degrees(self.elbow_socket),
                                     "the elbow sockets' angle must be within (-180, 180] degrees")
        if self.lb <= abs(self.R - self.r) - self.la:
            raise InvalidDesignError("lb", self.lb, f"the forearm cannot span the gap between the elbow circle "
                                     f"and the platform joint: need lb > |R - r| - la = {abs(self.R - self.r) - self.la:g} m")

    # Derived geometry, shape (3, 3): row i belongs to limb i (e, t: `LimbDesign`).
    @functools.cached_property
    def base_points(self) -> np.ndarray:
        """A_i = R e_i [m]: where each actuator axis crosses its limb's plane."""
        return self.R * self.e

    @functools.cached_property
    def platform_sockets(self) -> np.ndarray:
        """Unit platform socket axes s_P,i (up, tilted outward), shape (3, 3)."""
        k = self.platform_socket
        return math.sin(k) * self.e + math.cos(k) * np.array([0.0, 0.0, 1.0])


_Z = np.array([0.0, 0.0, 1.0])


def in_plane(params: DeltaParams, eps: np.ndarray) -> np.ndarray:
    """d_i(eps) = cos(eps) e_i - sin(eps) z for angles eps of shape S + (3,), S + (3, 3)."""
    eps = np.asarray(eps, dtype=float)
    return np.cos(eps)[..., None] * params.e - np.sin(eps)[..., None] * _Z


def _wrap(params: DeltaParams, theta: np.ndarray) -> np.ndarray:
    """Angles within pi of the middle of the actuator range."""
    centre = 0.5 * (params.theta_limits[0] + params.theta_limits[1])
    return (theta - centre + math.pi) % (2 * math.pi) + centre - math.pi


# -- inverse kinematics ----------------------------------------------------------------------
@dataclass(frozen=True)
class LimbSolutions(modes.LimbRoots):
    """Per-limb IK (`LimbRoots`): q the upper-arm angles [rad], n the forearm directions
    (C_i - E_i)/l_b; and

    Attributes:
        near: S + (3,) distance from C_i to the nearest point of the elbow circle [m].
        far: S + (3,) distance from C_i to the farthest point of the elbow circle [m];
            the limb reaches iff near <= l_b <= far.
    """

    near: np.ndarray
    far: np.ndarray


def limb_ik(params: DeltaParams, p: np.ndarray) -> LimbSolutions:
    """Both upper-arm angles theta = phi0 +/- atan2(sqrt(rho^2 - K^2), K) [rad] of every limb and
    the forearm directions they give, at every platform position p [m]."""
    v = modes.points(p)[..., None, :] + (params.r - params.R) * params.e  # C_i - A_i, S + (3, 3)
    x = np.einsum("...ij,ij->...i", v, params.e)
    y = np.einsum("...ij,ij->...i", v, params.t)
    h = v[..., 2]
    rho2 = x * x + h * h
    K = (rho2 + y * y + params.la**2 - params.lb**2) / (2 * params.la)
    disc = rho2 - K * K
    reach, s = modes.real_root(disc, params.lb)
    phi0 = np.arctan2(-h, x)
    half = np.arctan2(s, K)
    q = _wrap(params, np.stack([phi0 + half, phi0 - half], axis=-1))  # S + (3, 2)
    elbow = params.la * in_plane(params, q.swapaxes(-1, -2)).swapaxes(-2, -3)  # E_i - A_i, S + (3, 2, 3)
    n = (v[..., None, :] - elbow) / params.lb
    rho = np.sqrt(rho2)
    near = np.hypot(rho - params.la, y)
    far = np.hypot(rho + params.la, y)
    return LimbSolutions(q, n, reach, near, far)


def passive_angles(params: DeltaParams, theta: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Elbow U-joint angles (psi, phi) [rad] of forearm directions n at actuator angles theta.

    n = cos(phi) d_i(theta + elbow_socket + psi) + sin(phi) t_i: psi turns the rod in the limb's
    plane away from the elbow socket's axis (about t_i), phi swings it out of the plane.
    Shapes: theta S + (3,), n S + (3, 3).
    """
    ne = np.sum(n * params.e, axis=-1)
    nt = np.sum(n * params.t, axis=-1)
    phi = np.arcsin(np.clip(nt, -1.0, 1.0))
    psi = np.arctan2(-n[..., 2], ne) - theta - params.elbow_socket
    return np.remainder(psi + math.pi, 2 * math.pi) - math.pi, phi


def cone_angles(params: DeltaParams, theta: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(elbow, platform) ball-joint angles [rad]: each rod's angle from its socket axis.

    Shapes: theta S + (3,) with n S + (3, 3), or per root theta S + (3, 2) with n S + (3, 2, 3).
    """
    theta = np.asarray(theta, dtype=float)
    roots = theta.shape[-1:] == (2,)  # a root axis after the limb axis
    e = params.e[:, None, :] if roots else params.e
    sp = params.platform_sockets[:, None, :] if roots else params.platform_sockets
    eps = theta + params.elbow_socket
    s_e = np.cos(eps)[..., None] * e - np.sin(eps)[..., None] * _Z
    ce = np.sum(n * s_e, axis=-1)
    cp = -np.sum(n * sp, axis=-1)
    return np.arccos(np.clip(ce, -1.0, 1.0)), np.arccos(np.clip(cp, -1.0, 1.0))


def limb_limits(params: DeltaParams, limbs: LimbSolutions) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per limb and root: (theta ok, elbow cone ok, platform cone ok), each S + (3, 2)."""
    with np.errstate(invalid="ignore"):
        theta_ok = (limbs.q >= params.theta_limits[0] - ACTUATOR_TOL) & (limbs.q <= params.theta_limits[1] + ACTUATOR_TOL)
        ce, cp = cone_angles(params, limbs.q, limbs.n)
        return theta_ok, ce <= params.cone, cp <= params.cone


def ik(params: DeltaParams, p: np.ndarray, *, limits: bool = True) -> IKResult:
    """Inverse kinematics in all 8 working modes at every position p [m].

    Args:
        limits: check the ball-joint cones too; False checks the actuator range only.
    """
    limbs = limb_ik(params, p)
    theta_ok, elbow_ok, platform_ok = limb_limits(params, limbs)
    return modes.by_mode(limbs, theta_ok, elbow_ok & platform_ok, limits)


def limb_reasons(params: DeltaParams, limbs: LimbSolutions) -> list[dict[str, Any]]:
    """Per-limb reachability of one point, with the reason when a limb cannot reach."""
    out = []
    for i in range(3):
        ok = bool(limbs.reach[i])
        reason = None
        if not ok and limbs.near[i] > params.lb:
            reason = (f"limb {i + 1} cannot reach: its platform joint is {limbs.near[i]:.6g} m from the nearest "
                      f"point of its elbow circle, farther than the forearm l_b = {params.lb:g} m")
        elif not ok:
            reason = (f"limb {i + 1} cannot reach: its platform joint is at most {limbs.far[i]:.6g} m from its "
                      f"elbow circle, closer than the forearm l_b = {params.lb:g} m")
        out.append({"limb": i + 1, "reachable": ok, "reason": reason})
    return out


# -- forward kinematics ----------------------------------------------------------------------
def elbows(params: DeltaParams, q: np.ndarray) -> np.ndarray:
    """E_i = A_i + l_a d_i(theta_i) [m], shape S + (3, 3)."""
    q = modes.actuators(q, "angles")
    return params.base_points + params.la * in_plane(params, q)


def sphere_centres(params: DeltaParams, q: np.ndarray) -> np.ndarray:
    """c_i = E_i - r e_i: the platform centre lies at distance l_b from each, S + (3, 3)."""
    return elbows(params, q) - params.r * params.e


def fk(params: DeltaParams, q: np.ndarray) -> FKResult:
    """Forward kinematics: both assembly modes ("below", "above") for actuator angles q [rad];
    `gap` is how much longer the forearms would need to be where none exists [m]."""
    return intersect_spheres(sphere_centres(params, q), params.lb)


def fk_reason(params: DeltaParams, res: FKResult) -> str:
    """Why a single FK query has no assembly."""
    return (f"no assembly: the three spheres of radius l_b = {params.lb:g} m around the elbows (shifted by the "
            f"platform radius) do not meet (the forearms would need to be {float(res.gap):.6g} m longer)")


# -- velocity and singularities ---------------------------------------------------------------
def rod_vectors(params: DeltaParams, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """r_i = C_i - E_i [m], shape S + (3, 3)."""
    p = modes.points(p)
    return p[..., None, :] + params.r * params.e - elbows(params, q)


def jacobians(params: DeltaParams, p: np.ndarray, q: np.ndarray) -> Jacobians:
    """J_x, J_q, J = J_q^-1 J_x and the singularity measures at (p, q)."""
    r = rod_vectors(params, p, q)
    bhat = in_plane(params, np.asarray(q, dtype=float) + math.pi / 2)  # dE/dtheta / l_a
    n = modes.unit_rods(r)
    return modes.jacobians_of(r, params.la * np.sum(r * bhat, axis=-1), n, np.sum(n * bhat, axis=-1))


def jacobian_inverse(params: DeltaParams, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """J^-1 = J_x^-1 J_q: pdot = J^-1 thetadot [m/rad] (raises where J_x is singular)."""
    return modes.inverse_of(jacobians(params, p, q))


def violations(params: DeltaParams, q: np.ndarray, n: np.ndarray) -> list[str]:
    """Readable list of the limits a single pose breaks.

    Args:
        q: (3,) actuator angles [rad].
        n: (3, 3) unit forearm directions, row i for limb i.
    """
    deg = modes.angle_text
    ce, cp = cone_angles(params, np.asarray(q, dtype=float), np.asarray(n, dtype=float))
    lo, hi = params.theta_limits
    out = []
    for i in range(3):
        lim = f"limb {i + 1}: "
        if not lo - ACTUATOR_TOL <= q[i] <= hi + ACTUATOR_TOL:
            out.append(lim + f"theta = {deg(q[i])} outside [{deg(lo)}, {deg(hi)}]")
        if ce[i] > params.cone:
            out.append(lim + f"elbow ball joint at {deg(ce[i])} from its socket axis, beyond the cone's {deg(params.cone)}")
        if cp[i] > params.cone:
            out.append(lim + f"platform ball joint at {deg(cp[i])} from its socket axis, beyond the cone's "
                       f"{deg(params.cone)}")
    return out
