"""SCARA closed forms against Pinocchio, finite differences and their own inverses."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinematics.errors import InvalidInputError, UnsupportedRobotError
from kinematics.generic.serial import forward_kinematics, task_jacobian
from kinematics.mechanisms.scara import closed_form as sc
from kinematics.model.robot import load_robot

from .conftest import write_2r_urdf


@pytest.fixture(scope="module")
def params(scara):
    return sc.ScaraParams.from_robot(scara)


def test_parameters_read_from_urdf(params):
    # The values of paper A (l1 = 0.4 m, l2 = 0.3 m, +/-110 deg, +/-130 deg), read from the URDF.
    assert (params.l1, params.l2) == pytest.approx((0.4, 0.3), abs=1e-16)
    assert params.upper == pytest.approx((math.radians(110), math.radians(130)), abs=1e-16)


def test_reader_follows_the_urdf(tmp_path):
    path = tmp_path / "arm.urdf"
    write_2r_urdf(path, 1.3, 0.25, lim1=1.0, lim2=2.0)
    p = sc.ScaraParams.from_robot(load_robot(path))
    assert (p.l1, p.l2, p.lower, p.upper) == (1.3, 0.25, (-1.0, -2.0), (1.0, 2.0))


def test_reader_rejects_non_2r(ur5):
    with pytest.raises(UnsupportedRobotError, match="two revolute joints"):
        sc.ScaraParams.from_robot(ur5)


def test_closed_forms_match_pinocchio(scara, params, rng):
    qs = rng.uniform(params.lower, params.upper, (200, 2))
    xy = sc.fk(params, qs)
    J = sc.jacobian(params, qs)
    assert xy.shape == (200, 2) and J.shape == (200, 2, 2)
    for q, p, Jq in zip(qs, xy, J, strict=True):
        cq = scara.configuration(q)
        np.testing.assert_allclose(forward_kinematics(scara, cq).position[:2], p, rtol=0, atol=1e-12)
        np.testing.assert_allclose(task_jacobian(scara, cq), Jq, rtol=0, atol=1e-12)


def test_jacobian_matches_finite_differences(params, rng):
    qs = rng.uniform(params.lower, params.upper, (100, 2))
    h = 1e-6
    J = sc.jacobian(params, qs)
    for k in range(2):
        dq = np.zeros(2)
        dq[k] = h
        fd = (sc.fk(params, qs + dq) - sc.fk(params, qs - dq)) / (2 * h)
        np.testing.assert_allclose(J[:, :, k], fd, atol=1e-9)


def test_det_closed_form(scara, params, rng):
    """l1 l2 sin(theta2) against the determinant of Pinocchio's Jacobian (not of our own closed
    form's matrix). Entries <= 0.7 m: the 2 x 2 determinant's rounding is ~1e-16 m^2."""
    qs = rng.uniform(params.lower, params.upper, (200, 2))
    ref = [np.linalg.det(task_jacobian(scara, scara.configuration(q))) for q in qs]
    np.testing.assert_allclose(sc.det_jacobian(params, qs), ref, rtol=0, atol=1e-15)
    assert sc.det_jacobian(params, np.array([0.7, 0.0])) == 0.0


def test_ik_round_trip_vectorised(params, rng):
    qs = rng.uniform(params.lower, params.upper, (100_000, 2))
    xy = sc.fk(params, qs)
    res = sc.ik(params, xy)
    assert res.reachable.all()
    assert np.abs(sc.fk(params, res.q) - xy[:, None, :]).max() <= 1e-12
    # The original configuration is one of the two elbows (away from the ill-conditioned boundary).
    branch = (qs[:, 1] > 0).astype(int)  # ELBOWS = ("up": theta2 <= 0, "down": theta2 >= 0)
    recovered = res.q[np.arange(len(qs)), branch]
    ok = np.abs(qs[:, 1]) > 1e-3
    np.testing.assert_allclose(recovered[ok], qs[ok], atol=1e-11)
    assert res.within_limits[np.arange(len(qs)), branch].all()


PARAMS = sc.ScaraParams.from_robot(load_robot("scara"))


@settings(max_examples=200, deadline=None)
@given(
    st.floats(-math.radians(110), math.radians(110)),
    st.floats(-math.radians(130), math.radians(130)),
)
def test_ik_of_fk_property(t1, t2):
    p = PARAMS
    xy = sc.fk(p, np.array([t1, t2]))
    res = sc.ik(p, xy)
    assert res.reachable
    assert np.abs(sc.fk(p, res.q) - xy).max() <= 1e-12
    assert np.abs(res.q[0, 1]) == pytest.approx(np.abs(res.q[1, 1]))
    assert res.q[0, 1] <= 0 <= res.q[1, 1]


def test_ik_boundary_and_unreachable(params):
    ans = sc.solve_ik(params, (0.7, 0.0))
    assert ans.reachable and all(s.q == (0.0, 0.0) for s in ans.solutions)
    far = sc.solve_ik(params, (0.71, 0.0))
    assert not far.reachable and "outer radius" in far.reason and far.solutions == ()
    near = sc.solve_ik(params, (0.05, 0.0))
    assert not near.reachable and "inner radius" in near.reason


def test_ik_joint_limits_named(params):
    # Behind the base: geometrically reachable, but theta1 would exceed +/-110 deg on both elbows.
    ans = sc.solve_ik(params, (-0.5, -0.1))
    assert not ans.reachable
    assert len(ans.solutions) == 2 and not any(s.within_limits for s in ans.solutions)
    assert "joint1" in ans.reason
    # theta2 = +/-pi folds the arm: outside +/-130 deg.
    folded = sc.solve_ik(params, (0.1, 0.0))
    assert "joint2" in folded.reason


def test_ik_rejects_bad_input(params):
    with pytest.raises(InvalidInputError):
        sc.ik(params, np.array([np.nan, 0.2]))
    with pytest.raises(InvalidInputError):
        sc.solve_ik(params, (0.1, 0.2, 0.3))
    with pytest.raises(InvalidInputError):
        sc.fk(params, np.zeros(3))


@pytest.mark.parametrize("q", [[np.nan, 0.3], [np.inf, 0.3], [0.2, -np.inf]])
def test_fk_and_jacobians_refuse_non_finite_angles(q):
    """A NaN or inf joint angle is refused by the mechanism's fk and velocity as the IK refuses a
    NaN point (it came back as a NaN position flagged as existing, and NaN Jacobians)."""
    from kinematics.mechanisms import mechanism_of

    m = mechanism_of(load_robot("scara"))
    q = np.array([q])
    with pytest.raises(InvalidInputError, match="finite"):
        m.fk(q)
    with pytest.raises(InvalidInputError, match="finite"):
        m.velocity(np.zeros((1, 2)), q)


def test_fk_then_ik_on_a_joint_limit_stays_within():
    # a joint on its limit: the IK gives it back a few ulp beyond (atan2 round-off), which must
    # still count as within the limits (sampled poses with one joint on an end, both elbows)
    from kinematics.mechanisms import mechanism_of
    from kinematics.model.robot import load_robot

    m = mechanism_of(load_robot("scara"))
    lo, hi = np.array(m.params.lower), np.array(m.params.upper)
    rng = np.random.default_rng(0)
    for _ in range(200):
        q = rng.uniform(lo, hi)
        k = rng.integers(2)
        q[k] = (lo if rng.random() < 0.5 else hi)[k]
        ik = m.pose_ik(m.fk(q[None]).p[0, 0])
        back = [j for j in range(2) if ik.reachable[j] and np.abs(ik.q[j] - q).max() <= 1e-9]
        assert len(back) == 1 and ik.within_limits[back[0]] and ik.violations[back[0]] == (), q
