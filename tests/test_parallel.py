"""3-[P2(US)] closed forms: IK/FK, passive angles, Jacobians, singularity types."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from kinematics.errors import InvalidInputError, UnknownModeError
from kinematics.mechanisms.p2us import closed_form as par

from .conftest import sample_actuators


def test_modes():
    assert len(par.MODES) == 8 and len(set(par.MODES)) == 8
    assert par.MODES[0] == "+++" and par.MODES[-1] == "---"
    assert par.mode_index("+-+") == 2
    with pytest.raises(UnknownModeError) as info:
        par.mode_index("++")
    assert "+++" in info.value.valid


def test_ik_roots_satisfy_rod_constraint(p2us_params, rng):
    P = p2us_params
    p = rng.uniform([-0.4, -0.4, -0.8], [0.4, 0.4, 0.1], (100_000, 3))
    limbs = par.limb_ik(P, p)
    B = P.base_points[:, None, :] + limbs.q[..., None] * P.w[:, None, :]
    C = p[:, None, None, :] + P.d * P.e[:, None, :]
    err = np.abs(np.linalg.norm(C - B, axis=-1) - P.L)
    assert np.nanmax(err[limbs.reach]) <= 1e-12
    assert np.all(np.isnan(limbs.q[~limbs.reach]))
    # a limb reaches iff its platform joint is within L of the rail's axis
    assert np.array_equal(limbs.reach, limbs.axis_distance <= P.L) or np.all(
        np.abs(limbs.axis_distance[limbs.reach != (limbs.axis_distance <= P.L)] - P.L) < 1e-12)
    assert np.all(limbs.q[..., 0][limbs.reach] >= limbs.q[..., 1][limbs.reach])  # "+" is the larger root


def test_fk_ik_round_trip_vectorised(p2us_params, rng):
    P = p2us_params
    q = sample_actuators(P, 100_000, rng)
    res = par.fk(P, q)
    assert res.exists.all()
    for k in range(2):
        ik = par.ik(P, res.p[:, k])
        err = np.min(np.max(np.abs(ik.q - q[:, None, :]), axis=-1), axis=-1)  # the matching mode
        assert err.max() <= 1e-9
    # FK(IK(p)) recovers p in one of the assembly modes
    p = res.p[:, 0]
    back = par.fk(P, par.ik(P, p).q[:, -1])  # mode "---" where it exists
    ok = back.exists
    dist = np.min(np.linalg.norm(back.p[ok] - p[ok, None, :], axis=-1), axis=-1)
    assert ok.mean() > 0.5 and dist.max() <= 1e-9


def _stroke_at_home(P, z):
    """The actuator value putting the platform at (0, 0, z) in the smaller-q root, from the
    geometry's definitions (B = A + q w, C = p + d e, |C - B| = L) by a bracketing root solve,
    not from the code's quadratic."""
    from scipy.optimize import brentq

    A, w, C = P.b * P.e[0], P.w[0], np.array([0, 0, z]) + P.d * P.e[0]
    rod = lambda q: np.linalg.norm(C - A - q * w) - P.L
    qs = np.linspace(0.0, 1.0, 1001)
    k = np.flatnonzero(np.diff(np.sign([rod(q) for q in qs])))[0]
    return brentq(rod, qs[k], qs[k + 1], xtol=1e-15)


def test_fk_assembly_modes_and_unreachable(p2us_params):
    P = p2us_params
    q0 = _stroke_at_home(P, -0.45)
    res = par.fk(P, np.full(3, q0))
    assert res.exists and res.p[0, 2] < res.p[1, 2]  # "below" is the lower one
    # brentq's xtol 1e-15 m on q moves p by ~|dp/dq| 1e-15; 1e-12 m covers rounding of fk
    np.testing.assert_allclose(res.p[0], [0, 0, -0.45], atol=1e-12)
    far = par.fk(P, np.array([0.1, 0.6, 0.6]) * 5)
    assert not far.exists and far.gap > 0 and np.all(np.isnan(far.p))
    with pytest.raises(InvalidInputError):
        par.fk(P, np.array([0.1, np.nan, 0.2]))
    with pytest.raises(InvalidInputError):
        par.ik(P, np.array([0.1, 0.2]))


def test_passive_angles_reproduce_rod_direction(p2us_params, rng):
    P = p2us_params
    p = rng.uniform([-0.3, -0.3, -0.7], [0.3, 0.3, -0.1], (20_000, 3))
    limbs = par.limb_ik(P, p)
    theta, phi = par.passive_angles(P, limbs.n)
    eps = P.theta_zero + theta
    e, t = P.e[:, None, :], P.t[:, None, :]
    n = (np.cos(phi)[..., None] * (np.cos(eps)[..., None] * -e - np.sin(eps)[..., None] * np.array([0, 0, 1]))
         - np.sin(phi)[..., None] * t)
    ok = limbs.reach[..., None] & np.ones(2, bool)
    assert np.abs(n - limbs.n)[ok].max() <= 1e-12


def test_trig_free_limit_check_matches_angles(rng):
    from kinematics.mechanisms.p2us.closed_form import P2USParams

    for P in (P2USParams(), P2USParams(theta_zero=0.4), P2USParams(theta_limits=(-2.0, 2.5))):
        n = rng.normal(size=(50_000, 3, 3))
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
        theta, phi = par.passive_angles(P, n)
        theta_ok, phi_ok = par.passive_limits_ok(P, n)
        lo, hi = P.theta_limits
        ref_theta = (theta >= lo) & (theta <= hi)
        ref_phi = (phi >= P.phi_limits[0]) & (phi <= P.phi_limits[1])
        margin = np.minimum(np.abs(theta - lo), np.abs(theta - hi)) > 1e-9
        assert np.array_equal(theta_ok[margin], ref_theta[margin])
        assert np.array_equal(phi_ok, ref_phi)


def test_jacobians_against_finite_differences(p2us_params, rng):
    P = p2us_params
    q = sample_actuators(P, 200, rng)
    p = par.fk(P, q).p[:, 0]
    jac = par.jacobians(P, p, q)
    h = 1e-6

    def f(pp, qq):
        r = par.rod_vectors(P, pp, qq)
        return 0.5 * (np.sum(r * r, axis=-1) - P.L**2)

    for k in range(3):
        dp = np.zeros(3)
        dp[k] = h
        np.testing.assert_allclose((f(p + dp, q) - f(p - dp, q)) / (2 * h), jac.Jx[..., k], atol=1e-9)
        dq = np.zeros(3)
        dq[k] = h
        # J_x pdot = J_q qdot means J_q = -df/dq
        np.testing.assert_allclose(-(f(p, q + dq) - f(p, q - dq))[:, k] / (2 * h), jac.Jq[:, k], atol=1e-9)
    # J = dq/dp along the IK branch of each sample; central differences lose accuracy like
    # h^2 / iota_I^3 next to a type I singularity, so compare where the pose is well conditioned.
    good = jac.iota_I > 0.05
    p, q, J = p[good], q[good], jac.J[good]
    ik0 = par.ik(P, p)
    m = np.argmin(np.max(np.abs(ik0.q - q[:, None, :]), axis=-1), axis=-1)
    rows = np.arange(len(p))
    for k in range(3):
        dp = np.zeros(3)
        dp[k] = h
        fd = (par.ik(P, p + dp).q[rows, m] - par.ik(P, p - dp).q[rows, m]) / (2 * h)
        np.testing.assert_allclose(fd, J[..., k], rtol=1e-6, atol=1e-7)
    assert good.sum() > 100
    # J^-1 = dp/dq along the FK branch: central differences of the closed-form FK (a separate
    # path: sphere intersection, no Jacobian algebra). Same h and conditioning as above.
    inv = par.jacobian_inverse(P, p, q)
    mode = np.argmin(np.linalg.norm(par.fk(P, q).p - p[:, None, :], axis=-1), axis=-1)
    for k in range(3):
        dq = np.zeros(3)
        dq[k] = h
        fd = (par.fk(P, q + dq).p[rows, mode] - par.fk(P, q - dq).p[rows, mode]) / (2 * h)
        np.testing.assert_allclose(fd, inv[..., k], rtol=1e-6, atol=1e-7)


def test_type_one_rod_perpendicular_to_actuator(p2us_params):
    P = p2us_params
    # Limb 1's rod perpendicular to its rail: n1 = unit vector orthogonal to w1, in the limb's plane.
    n1 = np.cross(P.w[0], P.t[0])
    n1 /= np.linalg.norm(n1)
    if n1[2] > 0:
        n1 = -n1
    q1 = 0.3
    p = P.base_points[0] + q1 * P.w[0] + P.L * n1 - P.d * P.e[0]
    res = par.ik(P, p)
    m = np.flatnonzero(res.reachable)[0]
    jac = par.jacobians(P, p, res.q[m])
    assert abs(res.q[m, 0] - q1) < 1e-7  # the two roots of limb 1 merge at q1
    assert jac.iota_I <= par.SINGULAR_TOL and jac.iota_II > par.SINGULAR_TOL
    assert par.SINGULARITY_TYPES[int(par.classify(jac.iota_I, jac.iota_II))] == "type I"
    assert np.isinf(jac.J[0]).any() or np.abs(jac.J[0]).max() > 1e5


def type_two_pose(P):
    """A pose on the z axis, mode '---', where the three rods are coplanar (det n = 0), by bisection."""
    z = np.linspace(-0.2, 0.2, 4001)
    pts = np.stack([0 * z, 0 * z, z], -1)
    res = par.ik(P, pts)
    q = res.q[:, -1]
    ok = res.reachable[:, -1]
    det = np.linalg.det(par.jacobians(P, pts[ok], q[ok]).Jx)
    k = np.flatnonzero(np.diff(np.sign(det)))[0]
    lo, hi = pts[ok][k, 2], pts[ok][k + 1, 2]
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        dm = np.linalg.det(par.jacobians(P, np.array([0, 0, mid]), par.ik(P, np.array([0, 0, mid])).q[-1]).Jx)
        if np.sign(dm) == np.sign(det[k]):
            lo = mid
        else:
            hi = mid
    p = np.array([0.0, 0.0, 0.5 * (lo + hi)])
    return p, par.ik(P, p).q[-1]


def test_type_two_rods_coplanar(p2us_params):
    P = p2us_params
    p, q = type_two_pose(P)
    jac = par.jacobians(P, p, q)
    assert jac.iota_II <= par.SINGULAR_TOL and jac.iota_I > par.SINGULAR_TOL
    assert par.SINGULARITY_TYPES[int(par.classify(jac.iota_I, jac.iota_II))] == "type II"
    with pytest.raises(InvalidInputError, match="type II"):
        par.jacobian_inverse(P, p, q)


def test_classify_codes():
    got = par.classify(np.array([1, 0, 1, 0.0]), np.array([1, 1, 0, 0.0]))
    assert [par.SINGULARITY_TYPES[c] for c in got] == ["none", "type I", "type II", "type III"]


def test_paper_table3_does_not_reproduce(p2us_params):
    # Paper B Table 3: IK at (10, 10, -55) mm gives q = (39.354, 26.148, 36.635) mm. No working mode of
    # Table 2's geometry comes within a centimetre, under our sign convention or under eq. 8's
    # (q -> -q); docs/p2us.md explains. This pins the documented claim.
    paper = np.array([39.35419, 26.14763, 36.63527]) * 1e-3
    res = par.ik(p2us_params, np.array([0.010, 0.010, -0.055]))
    for sign in (1, -1):
        assert np.nanmin(np.abs(sign * res.q - paper).max(axis=-1)) > 0.01


def test_degrees_of_modes_at_home(p2us_params):
    res = par.ik(p2us_params, np.array([0.0, 0.0, -0.45]))
    assert list(np.array(par.MODES)[res.within_limits]) == ["---"]


# -- hardening (issue 11) -----------------------------------------------------------------------
def test_fk_shortfall_is_a_length():
    """Defect 4: where the spheres do not meet, `gap` is how much longer the rods must be [m]:
    the centres' circumradius (Heron's formula, independent of fk's frame) minus L, and rods
    that much longer (to 1e-9 relative) just assemble."""
    P = par.P2USParams()
    for q in (np.array([0.5, 3.0, 3.0]), np.array([0.6, 0.6, 2.2]), np.array([0.1, 0.6, 1.5])):
        res = par.fk(P, q)
        assert not res.exists
        c = par.sphere_centres(P, q)
        a, b, cc = (np.linalg.norm(c[i] - c[j]) for i, j in ((0, 1), (1, 2), (2, 0)))
        s = 0.5 * (a + b + cc)
        R = a * b * cc / (4 * np.sqrt(s * (s - a) * (s - b) * (s - cc)))
        assert res.gap == pytest.approx(R - P.L, rel=1e-12)
        assert par.fk(P.replace(L=P.L + res.gap * (1 + 1e-9)), q).exists
        assert not par.fk(P.replace(L=P.L + res.gap * (1 - 1e-6)), q).exists


def test_type_three_both_matrices_singular(p2us_params):
    """A type III pose built from the geometry alone: limb 1's rod perpendicular to its rail
    (n1 = cos u a + sin u c, a and c spanning the plane normal to w1, slider at 0.4 m), limbs 2
    and 3 closed by their own root solves, and u found by bisection where the rods become
    coplanar (det[n1; n2; n3] = 0). Then iota_I = 0 (to rounding) and iota_II = 0 (to brentq's
    xtol), so both are far below SINGULAR_TOL and the pose must be "type III"."""
    from scipy.optimize import brentq

    P = p2us_params
    w1 = P.w[0]
    a = np.cross(w1, P.t[0])
    a /= np.linalg.norm(a)
    c = np.cross(w1, a)
    q1 = 0.4  # at 0.3 m the rods only turn coplanar across the other limbs' reach gaps

    def pose(u, root):
        n1 = np.cos(u) * a + np.sin(u) * c
        p = P.base_points[0] + q1 * w1 + P.L * n1 - P.d * P.e[0]
        q, n = [q1], [n1]
        for i in (1, 2):
            v = p + P.d * P.e[i] - P.base_points[i]  # C_i - A_i; rod = v - q w_i
            B, C = -2 * v @ P.w[i], v @ v - P.L**2  # |v - q w|^2 = L^2: q^2 + B q + C = 0
            disc = B * B - 4 * C
            if disc < 0:
                return None
            qi = (-B + (1 if root[i - 1] else -1) * np.sqrt(disc)) / 2
            q.append(qi)
            n.append((v - qi * P.w[i]) / P.L)
        return p, np.array(q), np.array(n)

    u = np.linspace(0, 2 * np.pi, 721)
    found = None
    for root in itertools.product((0, 1), repeat=2):
        dets = [np.linalg.det(r[2]) if (r := pose(x, root)) is not None else np.nan for x in u]
        k = np.flatnonzero(np.isfinite(dets[:-1]) & np.isfinite(dets[1:]) & (np.sign(dets[:-1]) != np.sign(dets[1:])))
        if k.size:
            found = brentq(lambda x, root=root: np.linalg.det(pose(x, root)[2]), u[k[0]], u[k[0] + 1], xtol=1e-15), root
            break
    assert found is not None
    p, q, _ = pose(*found)
    jac = par.jacobians(P, p, q)
    assert jac.iota_I < 1e-12 and jac.iota_II < 1e-12
    assert par.SINGULARITY_TYPES[int(par.classify(jac.iota_I, jac.iota_II))] == "type III"
    assert abs(jac.Jq[0]) < 1e-12 and abs(np.linalg.det(jac.Jx)) < 1e-12 * P.L**3
