"""Delta closed forms: IK/FK, cones, Jacobians, singularity types, design validation.

Oracles are independent of the code under test: scipy root solves of the loop equations written
here from the definitions (E = A + la d(theta), C = p + r e, |C - E| = lb), finite differences of
IK/FK, and poses built from geometry.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinematics.errors import InvalidDesignError, InvalidInputError
from kinematics.mechanisms.delta import closed_form as dl

P = dl.DeltaParams()
Z = np.array([0.0, 0.0, 1.0])


def elbow(P, i, theta):
    """E_i from the definition (not from the module)."""
    e = np.array([math.cos(P.alpha[i]), math.sin(P.alpha[i]), 0.0])
    return P.R * e + P.la * (math.cos(theta) * e - math.sin(theta) * Z)


def sample_actuators(P, n, rng):
    """Actuator angles within the range at which the robot assembles (rejection sampling)."""
    out = []
    while sum(len(o) for o in out) < n:
        q = rng.uniform(*P.theta_limits, (4 * n, 3))
        out.append(q[dl.fk(P, q).exists])
    return np.concatenate(out)[:n]


def test_ik_roots_satisfy_forearm_constraint(rng):
    p = rng.uniform([-0.6, -0.6, -1.3], [0.6, 0.6, 0.1], (100_000, 3))
    limbs = dl.limb_ik(P, p)
    E = P.base_points[:, None, :] + P.la * (np.cos(limbs.q)[..., None] * P.e[:, None, :]
                                            - np.sin(limbs.q)[..., None] * Z)
    C = p[:, None, None, :] + P.r * P.e[:, None, :]
    err = np.abs(np.linalg.norm(C - E, axis=-1) - P.lb)
    assert np.nanmax(err[limbs.reach]) <= 1e-12  # m; rounding of O(1 m) quantities
    assert np.all(np.isnan(limbs.q[~limbs.reach]))
    # a limb reaches iff the forearm length lies between the nearest and farthest elbow-circle distances
    inside = (limbs.near <= P.lb) & (P.lb <= limbs.far)
    differ = limbs.reach != inside
    assert np.all(np.minimum(np.abs(limbs.near - P.lb), np.abs(limbs.far - P.lb))[differ] < 1e-12)
    assert 0.2 < limbs.reach.mean() < 0.9  # the sample straddles the boundary
    # every limb angle lies within pi of the middle of the actuator range
    centre = 0.5 * sum(P.theta_limits)
    assert np.all(np.abs(limbs.q[limbs.reach] - centre) <= math.pi + 1e-12)


def test_ik_matches_scipy_roots(rng):
    """Each limb's two angles are the two zeros of |C_i - E_i(theta)| - lb over a full turn,
    bracketed on a 1-degree grid and polished by brentq (xtol 1e-14 rad)."""
    from scipy.optimize import brentq

    pts = rng.uniform([-0.3, -0.3, -1.0], [0.3, 0.3, -0.6], (20, 3))
    res = dl.limb_ik(P, pts)
    checked = 0
    for p, q, reach in zip(pts, res.q, res.reach, strict=True):
        for i in range(3):
            if not reach[i]:
                continue
            C = p + P.r * np.array([math.cos(P.alpha[i]), math.sin(P.alpha[i]), 0.0])
            g = lambda th, C=C, i=i: np.linalg.norm(C - elbow(P, i, th)) - P.lb
            grid = np.radians(np.arange(-180.0, 181.0, 1.0)) + 0.5 * sum(P.theta_limits)
            vals = np.array([g(t) for t in grid])
            k = np.flatnonzero(np.sign(vals[:-1]) != np.sign(vals[1:]))
            roots = sorted(brentq(g, grid[j], grid[j + 1], xtol=1e-14) for j in k)
            assert len(roots) == 2
            np.testing.assert_allclose(sorted(q[i]), roots, atol=1e-9)  # rad
            checked += 1
    assert checked >= 40


def test_root_labels_by_geometry(rng):
    """Root "+" turns the arm from the line actuator axis -> platform joint (in the limb's plane)
    towards increasing theta: (E - A) x (C - A) . t_i <= 0; at the home column "-" is the
    elbow-out Delta (elbow farther from the axis than the platform joint)."""
    p = rng.uniform([-0.3, -0.3, -1.0], [0.3, 0.3, -0.6], (2000, 3))
    limbs = dl.limb_ik(P, p)
    for root, sign in ((0, -1), (1, 1)):
        for i in range(3):
            ok = limbs.reach[:, i]
            E = np.array([elbow(P, i, th) for th in limbs.q[ok, i, root]]) - P.base_points[i]
            C = p[ok] + (P.r - P.R) * P.e[i]
            side = np.cross(E, C) @ P.t[i]
            assert np.all(sign * side >= -1e-12)
    home = dl.limb_ik(P, np.array([0.0, 0.0, -0.85]))
    assert P.la * math.cos(home.q[0, 1]) > 0 > P.la * math.cos(home.q[0, 0])


def test_fk_ik_round_trip_vectorised(rng):
    q = sample_actuators(P, 100_000, rng)
    res = dl.fk(P, q)
    assert res.exists.all()
    for k in range(2):
        ik = dl.ik(P, res.p[:, k])
        err = np.min(np.max(np.abs(ik.q - q[:, None, :]), axis=-1), axis=-1)
        assert err.max() <= 1e-9
    below = res.p[:, 0]
    back = dl.fk(P, dl.ik(P, below).q[:, -1])
    ok = back.exists
    dist = np.min(np.linalg.norm(back.p[ok] - below[ok, None, :], axis=-1), axis=-1)
    assert ok.mean() > 0.5 and dist.max() <= 1e-9


def test_fk_no_assembly_gap_is_a_length():
    """Where the spheres do not meet, forearms `gap` longer (to 1e-9 relative) just assemble.
    Short forearms (0.3 m) and arms raised: the centres' circumradius is 0.2 + 0.3 cos(40 deg)
    - 0.05 = 0.38 m, so the gap is 0.08 m (built from the design, not from fk)."""
    D = P.replace(lb=0.3)
    for q in (np.radians([-40, -40, -40]), np.radians([-40, -30, 0])):
        res = dl.fk(D, q)
        assert not res.exists and res.gap > 0 and np.all(np.isnan(res.p))
        assert dl.fk(D.replace(lb=D.lb + res.gap * (1 + 1e-9)), q).exists
        assert not dl.fk(D.replace(lb=D.lb + res.gap * (1 - 1e-6)), q).exists
    sym = dl.fk(D, np.radians([-40, -40, -40]))
    assert sym.gap == pytest.approx(D.R + D.la * math.cos(math.radians(40)) - D.r - D.lb, rel=1e-12)


def test_home_column_modes_and_limits():
    res = dl.ik(P, np.array([0.0, 0.0, -0.85]))
    assert list(np.array(dl.MODES)[res.within_limits]) == ["---"]
    assert res.reachable.all()


def test_cone_angles_from_geometry(rng):
    """The cone angles are the angles between the rod and socket axes built here from the design:
    the elbow socket is the upper arm turned down by elbow_socket in the limb's plane; the
    platform socket points up, tilted outward by platform_socket."""
    p = rng.uniform([-0.3, -0.3, -1.0], [0.3, 0.3, -0.6], (500, 3))
    res = dl.ik(P, p)
    ok = res.reachable[:, -1]
    q, n = res.q[ok, -1], res.limbs.n[ok][:, np.arange(3), 1]
    ce, cp = dl.cone_angles(P, q, n)
    for i in range(3):
        e = P.e[i]
        for k in range(len(q)):
            eps = q[k, i] + P.elbow_socket
            s_e = math.cos(eps) * e - math.sin(eps) * Z
            s_p = math.sin(P.platform_socket) * e + math.cos(P.platform_socket) * Z
            rod = (p[ok][k] + P.r * e) - elbow(P, i, q[k, i])  # elbow -> platform
            rod /= np.linalg.norm(rod)
            assert abs(math.acos(np.clip(rod @ s_e, -1, 1)) - ce[k, i]) < 1e-7
            assert abs(math.acos(np.clip(-rod @ s_p, -1, 1)) - cp[k, i]) < 1e-7
    within = res.within_limits[ok, -1]
    expect = np.all((ce <= P.cone) & (cp <= P.cone) & (q >= P.theta_limits[0]) & (q <= P.theta_limits[1]), axis=-1)
    assert np.array_equal(within, expect) and 0 < within.mean() < 1


def test_passive_angles_reproduce_rod_direction(rng):
    p = rng.uniform([-0.3, -0.3, -1.0], [0.3, 0.3, -0.6], (5000, 3))
    limbs = dl.limb_ik(P, p)
    ok = limbs.reach.all(axis=-1)
    q, n = limbs.q[ok][:, :, 1], limbs.n[ok][:, :, 1]
    psi, phi = dl.passive_angles(P, q, n)
    eps = q + P.elbow_socket + psi
    back = np.cos(phi)[..., None] * (np.cos(eps)[..., None] * P.e - np.sin(eps)[..., None] * Z) \
        + np.sin(phi)[..., None] * P.t
    assert np.abs(back - n).max() <= 1e-12


def test_jacobians_against_finite_differences(rng):
    """J = dtheta/dp along each IK branch and J^-1 = dp/dtheta along the FK branch, against
    central differences (h = 1e-6: truncation ~h^2, rounding ~1e-16/h; rtol 1e-6, atol 1e-7)
    where the pose is well conditioned (iota_I, iota_II > 0.05)."""
    q = sample_actuators(P, 300, rng)
    p = dl.fk(P, q).p[:, 0]
    jac = dl.jacobians(P, p, q)
    good = (jac.iota_I > 0.05) & (jac.iota_II > 0.05)
    assert good.sum() > 100
    p, q, J = p[good], q[good], jac.J[good]
    h, rows = 1e-6, np.arange(good.sum())
    m = np.argmin(np.max(np.abs(dl.ik(P, p).q - q[:, None, :]), axis=-1), axis=-1)
    for k in range(3):
        dp = np.zeros(3)
        dp[k] = h
        fd = (dl.ik(P, p + dp).q[rows, m] - dl.ik(P, p - dp).q[rows, m]) / (2 * h)
        np.testing.assert_allclose(fd, J[..., k], rtol=1e-6, atol=1e-7)
    inv = dl.jacobian_inverse(P, p, q)
    for k in range(3):
        dq = np.zeros(3)
        dq[k] = h
        fd = (dl.fk(P, q + dq).p[:, 0] - dl.fk(P, q - dq).p[:, 0]) / (2 * h)
        np.testing.assert_allclose(fd, inv[..., k], rtol=1e-6, atol=1e-7)


def test_type_one_forearm_in_arm_and_axis_plane():
    """Limb 1's forearm in the plane of its upper arm and actuator axis (perpendicular to the
    elbow's velocity), built from geometry: arm straight down, forearm folded back up along it
    and 0.2 rad out of the limb's plane (the stretched poses leave the other limbs' reach).
    The pose is type I and limb 1's two roots merge at its angle."""
    th = math.pi / 2
    e, t = P.e[0], P.t[0]
    u = math.cos(th) * e - math.sin(th) * Z  # upper arm
    n1 = -(math.cos(0.2) * u + math.sin(0.2) * t)  # forearm folded back along the arm
    p = elbow(P, 0, th) + P.lb * n1 - P.r * e
    res = dl.limb_ik(P, p)
    # the double root: sqrt of a discriminant that rounding leaves at ~1e-16 m^2 -> ~1e-8 rad
    assert res.reach[0] and abs(res.q[0, 0] - res.q[0, 1]) < 1e-6 and abs(res.q[0, 0] - th) < 1e-6
    ik = dl.ik(P, p)
    m = np.flatnonzero(ik.reachable)[0]
    jac = dl.jacobians(P, p, ik.q[m])
    assert jac.iota_I <= dl.SINGULAR_TOL and jac.iota_II > dl.SINGULAR_TOL
    assert dl.SINGULARITY_TYPES[int(dl.classify(jac.iota_I, jac.iota_II))] == "type I"
    assert abs(jac.Jq[0]) <= 1e-6 * P.la * P.lb


def type_two_pose(P):
    """All three forearms vertical (parallel, so coplanar directions): theta with
    R + la cos(theta) = r, i.e. the elbows straight above the platform joints."""
    th = math.acos((P.r - P.R) / P.la)
    return np.array([0.0, 0.0, -P.la * math.sin(th) - P.lb]), np.full(3, th)


def test_type_two_forearms_parallel():
    p, q = type_two_pose(P)
    jac = dl.jacobians(P, p, q)
    assert jac.iota_II <= dl.SINGULAR_TOL and jac.iota_I > 0.1
    assert abs(np.linalg.det(jac.Jx)) < 1e-12 * P.lb**3
    assert dl.SINGULARITY_TYPES[int(dl.classify(jac.iota_I, jac.iota_II))] == "type II"
    with pytest.raises(InvalidInputError, match="type II"):
        dl.jacobian_inverse(P, p, q)


def test_type_three_both():
    """Type III built from geometry: a design with r = R puts each elbow straight above its
    platform joint when the arm points down (theta = 90 deg); the forearms then hang vertically
    (parallel: type II) and continue their arms (stretched: type I)."""
    D = P.replace(r=P.R)  # elbows above the platform joints at theta = 90 deg
    p = np.array([0.0, 0.0, -D.la - D.lb])
    jac = dl.jacobians(D, p, np.full(3, math.pi / 2))
    assert jac.iota_I < 1e-12 and jac.iota_II < 1e-12
    assert dl.SINGULARITY_TYPES[int(dl.classify(jac.iota_I, jac.iota_II))] == "type III"


def test_input_errors():
    with pytest.raises(InvalidInputError):
        dl.fk(P, np.array([0.1, np.nan, 0.2]))
    with pytest.raises(InvalidInputError):
        dl.ik(P, np.array([0.1, 0.2]))


def test_unreachable_reasons():
    far = dl.limb_ik(P, np.array([2.0, 0.0, -0.8]))
    reasons = dl.limb_reasons(P, far)
    assert all(not r["reachable"] and "farther than the forearm" in r["reason"] for r in reasons)
    # the platform joint right at the actuator axis: the whole elbow circle is within la < lb
    near = dl.limb_ik(P, np.array([P.R - P.r, 0.0, 0.0]))
    r1 = dl.limb_reasons(P, near)[0]
    assert not r1["reachable"] and "closer than the forearm" in r1["reason"]


@pytest.mark.parametrize(("change", "parameter"), [
    ({"alpha": (0.0, 0.0, 1.0)}, "alpha"),
    ({"alpha": (0.0, 2 * math.pi, 2.0)}, "alpha"),
    ({"cone": 0.0}, "cone"),
    ({"cone": math.radians(95)}, "cone"),
    ({"platform_socket": math.radians(-5)}, "platform_socket"),
    ({"theta_limits": (math.radians(-200), 0.5)}, "theta_limits"),
    ({"R": 2.0, "la": 0.3, "lb": 0.5}, "lb"),  # the forearm cannot span |R - r| - la = 1.65 m
])
def test_degenerate_designs_rejected(change, parameter):
    with pytest.raises(InvalidDesignError) as info:
        P.replace(**change)
    assert info.value.parameter == parameter and "\n" not in str(info.value)


def test_invalid_parameters_rejected():
    for bad in ({"lb": -1.0}, {"R": float("nan")}, {"theta_limits": (1.0, 0.5)}, {"rod_spacing": 0.0}):
        with pytest.raises(InvalidInputError):
            P.replace(**bad)
    # a valid change: that parameter changed, every other one kept
    D = dl.DeltaParams(R=0.25, r=0.04)
    assert D.replace(lb=0.7, cone=0.5) == dl.DeltaParams(R=0.25, r=0.04, lb=0.7, cone=0.5)
