"""The guidance controller: eq. 16, the cos^2 projection, saturation, IK with limits, paper A's
three experiments and their baselines, any serial robot, and the `guide` CLI."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinematics.errors import InvalidInputError
from kinematics.generic.manipulability import ellipsoid
from kinematics.guidance.controller import (
    Controller,
    GuidanceParams,
    ScaraKinematics,
    SerialKinematics,
    virtual_gain,
)
from kinematics.guidance.simulation import (
    SINGULAR_RADIUS,
    Profile,
    ReactiveOperator,
    StubbornOperator,
    run_experiment,
    simulate,
)
from kinematics.mechanisms.scara.closed_form import ScaraParams, fk, jacobian

from .test_cli import run, run_json


@pytest.fixture(scope="module")
def sp(scara):
    return ScaraParams.from_robot(scara)


@pytest.fixture(scope="module")
def runs(sp):
    return {(n, vi): run_experiment(n, sp, GuidanceParams(virtual_impedance=vi)) for n in (1, 2, 3) for vi in (True, False)}


def test_eq16_step():
    p = GuidanceParams()
    assert virtual_gain(p, 0.1) == pytest.approx(125.0)
    assert virtual_gain(p, 0.0) == pytest.approx(250 / math.pi * math.atan(1e3) + 125)
    assert virtual_gain(p, 0.2) < 0.3 and virtual_gain(p, 0.05) > 249
    r = np.linspace(0, 0.3, 301)
    k = np.array([virtual_gain(p, x) for x in r])
    assert np.all(np.diff(k) <= 0) and np.all((k >= 0) & (k <= 250))
    assert virtual_gain(p, -0.05) == virtual_gain(p, 0.05)  # |r|


def test_scalar_ellipse_matches_manipulability(sp, rng):
    kin = ScaraKinematics(sp)
    for q in rng.uniform(sp.lower, sp.upper, (200, 2)):
        radii, u = kin.ellipse(q)
        ref = ellipsoid(jacobian(sp, q))
        np.testing.assert_allclose(radii, ref.radii, atol=1e-9)
        assert abs(abs(np.dot(u, ref.directions[0])) - 1) < 1e-9 or ref.radii[1] - ref.radii[0] < 1e-9
        np.testing.assert_allclose(kin.fk(q), fk(sp, q), atol=1e-15)


def test_ik_respects_limits_and_branch(sp, rng):
    kin = ScaraKinematics(sp)
    for q in rng.uniform(sp.lower, sp.upper, (200, 2)):
        back = kin.ik(fk(sp, q), q)
        np.testing.assert_allclose(back, q, atol=1e-9)
    assert kin.ik(np.array([0.75, 0.0]), np.zeros(2)) is None  # out of reach
    assert kin.ik(np.array([-0.5, -0.05]), np.array([0.0, 0.5])) is None  # joint 1 beyond 110 deg


def test_cos2_projection(sp):
    """One step from rest inside the threshold: the spring is zero at the rest point, so the
    velocity change per axis is dt (F - 0) / M and the damping enters as (B + K_v u_j^2)."""
    kin = ScaraKinematics(sp)
    p = GuidanceParams()
    q = kin.ik(np.array([0.68, 0.02]), np.array([0.0, -1.0]))
    ctrl = Controller(kin, p, q)
    ctrl.v = np.array([0.1, 0.05])
    radii, u = kin.ellipse(q)
    assert radii[0] < p.threshold
    f = np.array([3.0, -2.0])
    s = ctrl.step(f)
    k = virtual_gain(p, radii[0])
    ctrl_v = np.array([0.1, 0.05])
    expect = ctrl_v + p.dt * (f - (p.damping + k * np.square(u)) * ctrl_v) / p.mass
    np.testing.assert_allclose(s.v_raw, expect, atol=1e-15)
    assert s.k_v == pytest.approx(k)
    # second step: the spring acts along each axis with K_v u_j^2 (x_j - rest_j)
    x_rest = ctrl.rest.copy()
    v1, x1 = s.v.copy(), s.x.copy()
    s2 = ctrl.step(f)
    radii2, u2 = kin.ellipse(s.q)
    k2 = virtual_gain(p, radii2[0])
    c2 = np.square(u2)
    expect2 = v1 + p.dt * (f - k2 * c2 * (x1 - x_rest) - (p.damping + k2 * c2) * v1) / p.mass
    np.testing.assert_allclose(s2.v_raw, expect2, atol=1e-15)


@pytest.mark.parametrize("mode", ["norm", "axis"])
def test_saturation_is_integrated(sp, mode):
    kin = ScaraKinematics(sp)
    p = GuidanceParams(saturation=mode)
    q0 = kin.ik(np.array([0.45, 0.1]), np.array([0.0, -1.0]))
    ctrl = Controller(kin, p, q0)
    x_prev = ctrl.x.copy()
    for _ in range(400):
        s = ctrl.step(np.array([-40.0, -40.0]))
        assert not s.blocked
        np.testing.assert_allclose(s.x, x_prev + p.dt * s.v, atol=1e-15)  # the saturated v moves the tip
        x_prev = s.x
    if mode == "norm":
        assert np.linalg.norm(s.v) == pytest.approx(p.v_max)
    else:
        np.testing.assert_allclose(np.abs(s.v), p.v_max)
    assert s.saturated and np.linalg.norm(s.v_raw) > np.linalg.norm(s.v)


def test_experiment_1_saturation(runs):
    r = runs[1, True]
    s = r.summary()
    assert s["max_speed"] <= 0.25 + 1e-12
    assert len(s["saturated_intervals"]) == 1 and s["saturated_seconds"] > 1.0  # one contiguous interval
    a, b = s["saturated_intervals"][0]
    assert r.saturated[(r.t >= a) & (r.t <= b)].all()
    assert s["min_radius"] > 0.1 and s["max_raw_speed"] > 0.25


def test_experiment_2_stops_short(runs):
    s, base = runs[2, True].summary(), runs[2, False].summary()
    x_final = s["final_position"][0]
    assert x_final < 0.7 - 0.02 and not s["reached_singularity"]
    r = runs[2, True]
    crossed = np.flatnonzero(r.radii[:, 0] < 0.1)[0]
    assert r.x[crossed, 0] < x_final + 0.01  # it stops near where the radius crossed the threshold
    assert abs(r.v[-1]).max() < 1e-3
    assert base["reached_singularity"] and base["final_position"][0] > 0.7 - 1e-4


def test_experiment_3_never_singular(runs):
    r = runs[3, True]
    s = r.summary()
    assert not s["reached_singularity"] and s["min_abs_theta2"] > 0.2
    assert s["min_radius"] > SINGULAR_RADIUS
    on = r.k_v > 1.0
    first = np.flatnonzero(on)[0]
    early = slice(first, first + 1000)
    late = slice(-1000, None)
    assert np.ptp(r.v[late, 0]) < 0.1 * np.ptp(r.v[early, 0])  # velocity transients die out
    assert np.ptp(r.k_v[late]) < 0.1 * np.ptp(r.k_v[early])
    base = runs[3, False].summary()
    assert base["reached_singularity"] and base["min_abs_theta2"] < 0.01
    assert base["peak_joint_speed"] > 5 * s["peak_joint_speed"]  # what the method buys


def test_operators():
    p = Profile("ramp", (1.0, 0.0), 10.0, 1.0, 2.0)
    assert p(0.5, None) == 0 and p(1.5, None) == pytest.approx(5) and p(3, None) == 10
    assert Profile("pulse", (1.0,), 4.0, 1.0, 2.0)(2.5, None) == 0
    with pytest.raises(InvalidInputError, match="force"):
        Profile("step", (1.0,), -1.0, 0.0)
    with pytest.raises(InvalidInputError, match="force"):
        StubbornOperator((1.0, 0.0), math.nan)
    op = ReactiveOperator((1.0, 0.0), 5.0, t0=0.0, rise=0.1, feel=10.0, delay=0.2)

    class S:
        k_v = 20.0

    assert op(1.0, None) == 5.0
    op(1.0, S())
    assert op(1.1, S()) == 5.0  # still within the reaction delay
    op(1.25, S())
    assert op(1.4, S()) == 0.0


def test_bad_parameters():
    for bad in ({"mass": -1.0}, {"damping": math.nan}, {"v_max": 0.0}, {"dt": math.inf}, {"saturation": "x"}):
        with pytest.raises(InvalidInputError):
            GuidanceParams(**bad)


def test_a_start_that_is_no_configuration_is_refused(sp, ur5):
    """A NaN start ran a whole NaN simulation on the SCARA and ended in numpy's 'eigenvalues did not
    converge' on the UR5; a short one was an IndexError or Pinocchio's C++ ValueError."""
    op = StubbornOperator((1.0, 0.0), 5.0)
    for kin, bad in ((ScaraKinematics(sp), [math.nan, 0.3]), (ScaraKinematics(sp), [0.3]),
                     (SerialKinematics(ur5), np.full(6, math.nan)), (SerialKinematics(ur5), np.zeros(5)),
                     (SerialKinematics(ur5), np.zeros((1, 6)))):
        with pytest.raises(InvalidInputError, match="^q: "):
            Controller(kin, GuidanceParams(), np.asarray(bad, dtype=float))
        with pytest.raises(InvalidInputError, match="^q: "):
            simulate(kin, GuidanceParams(), np.asarray(bad, dtype=float), op, (1.0,) + (0.0,) * (kin.dim - 1), 0.01)


def test_any_serial_robot(ur5):
    """The controller on UR5's translational ellipsoid: guided into the stretched singularity."""
    kin = SerialKinematics(ur5)
    q0 = np.array([0.0, -1.2, 1.6, -1.9, -1.57, 0.0])
    x0 = kin.fk(q0)
    radii, u = kin.ellipse(q0)
    J = __import__("kinematics.generic.serial", fromlist=["task_jacobian"]).task_jacobian(ur5, q0)
    np.testing.assert_allclose(radii, ellipsoid(J).radii, atol=1e-9)
    away = x0 / np.linalg.norm(x0)
    away[2] = 0.0
    for vi in (True, False):
        p = GuidanceParams(virtual_impedance=vi, threshold=0.15)
        r = simulate(kin, p, q0, Profile("step", tuple(away), 6.0, 0.2), away, 6.0)
        s = r.summary()
        assert np.all(np.linalg.norm(r.v, axis=1) <= 0.25 + 1e-12)
        assert np.all(r.q >= ur5.lower - 1e-12) and np.all(r.q <= ur5.upper + 1e-12)
        assert s["min_abs_theta2"] is None
        if vi:
            assert s["min_radius"] > 0.05 and s["max_k_v"] > 200
        else:
            assert s["min_radius"] < 0.05


def test_guide_cli(capsys, tmp_path):
    png, csv = tmp_path / "g.png", tmp_path / "g.csv"
    code, d, _ = run_json(capsys, "guide", "--experiment", "3", "--plot", str(png), "--csv", str(csv))
    keys = {"max_speed", "saturated_seconds", "min_radius", "final_position", "min_abs_theta2",
            "peak_joint_speed", "reached_singularity"}
    assert code == 0 and keys <= set(d) and d["reached_singularity"] is False
    assert png.read_bytes()[:4] == b"\x89PNG"
    lines = csv.read_text().splitlines()
    assert lines[0].startswith("t,Fx,Fy,x,y") and len(lines) == 9001
    code, d, _ = run_json(capsys, "guide", "--experiment", "3", "--no-virtual-impedance")
    assert code == 0 and d["reached_singularity"] is True
    code, out, _ = run(capsys, "guide", "--experiment", "1")
    assert code == 0 and "saturated" in out
    for bad in (["--mass", "-1"], ["--force", "nan"], ["--dt", "0"], ["--robot", "p2us"]):
        code, out, err = run(capsys, "guide", "--experiment", "2", *bad)
        assert code == 2 and out == "" and len(err.strip().splitlines()) == 1


# -- hardening (issue 11) -----------------------------------------------------------------------
def test_no_elbow_flip_at_the_joint1_limit(sp):
    """Defect 1: at theta1 = 110 deg - 1e-4 rad, elbow up (q2 = -1), a tangential push that
    would take joint 1 past its limit must hold the arm, not jump to the other elbow (q2 = +1,
    q2dot ~ 2000 rad/s). Bound: with |v| <= 0.25 m/s and |J^-1| <= 1/r_min, a step moves each
    joint by at most 0.25 * 1e-3 / r_min ~ 1e-3 rad here; 10 rad/s is two decades above that."""
    kin = ScaraKinematics(sp)
    q0 = np.array([math.radians(110) - 1e-4, -1.0])
    x0 = kin.fk(q0)
    push = 10.0 * np.array([-x0[1], x0[0]]) / np.linalg.norm(x0)  # tangential, increasing theta1
    ctrl = Controller(kin, GuidanceParams(), q0)
    steps = [ctrl.step(push) for _ in range(50)]
    assert all(np.abs(s.qdot).max() < 10.0 for s in steps)
    assert all(s.q[1] < 0 for s in steps)  # never the other elbow
    assert all(s.q[0] <= sp.upper[0] for s in steps)
    held = [s for s in steps if s.blocked]
    assert held and all(not s.v.any() for s in held)
    assert "joint1" in held[0].reason and "other elbow" in held[0].reason
    assert all(s.reason is None for s in steps if not s.blocked)
    run = simulate(kin, GuidanceParams(), q0, Profile("step", tuple(push / 10.0), 10.0, 0.0), push, 0.05)
    assert run.summary()["blocked_steps"] > 0 and "other elbow" in run.summary()["first_refusal"]


def test_ik_holds_branch_and_stretched_is_either(sp):
    kin = ScaraKinematics(sp)
    # a target the current (up) elbow reaches only beyond joint 1's limit, the down elbow within
    q_up = np.array([math.radians(110) - 1e-4, -1.0])
    target = fk(sp, np.array([math.radians(110) + 1e-3, -1.0]))
    assert kin.ik(target, q_up) is None
    down = kin.ik(target, np.array([1.0, 1.0]))
    assert down is not None and down[1] > 0
    np.testing.assert_allclose(fk(sp, down), target, atol=1e-12)
    # from the stretched pose (theta2 = 0) either elbow continues: the nearer one is taken
    q = kin.ik(np.array([0.69, 0.01]), np.array([0.0, 0.0]))
    assert q is not None and np.abs(q).max() < 0.5


def test_scalar_closed_forms_match_vectorised(sp, rng):
    """The guidance adapter's scalar forms are the library's: same IK (incl. within
    BOUNDARY_TOL of the outer radius, where acos would lose half the digits) and radii."""
    from kinematics.mechanisms.scara.closed_form import (
        BOUNDARY_TOL,
        ellipse_point,
        ik,
        ik_elbow,
        manipulability,
    )

    pts = rng.uniform(-0.7, 0.7, (300, 2))
    ang = rng.uniform(-np.pi, np.pi, 50)
    outer = sp.l1 + sp.l2
    edge = (outer * (1 + rng.uniform(-1, 1, 50) * BOUNDARY_TOL))[:, None] * np.stack([np.cos(ang), np.sin(ang)], -1)
    pts = np.concatenate([pts, edge])
    ref = ik(sp, pts)
    for k, sign in enumerate((-1.0, 1.0)):
        for xy, qr, ok in zip(pts, ref.q[:, k], ref.reachable, strict=True):
            got = ik_elbow(sp, xy[0], xy[1], sign)
            assert (got is not None) == ok
            if ok:
                assert got == (qr[0], qr[1]) or np.allclose(got, qr, atol=1e-15, rtol=0)
    qs = rng.uniform(sp.lower, sp.upper, (200, 2))
    m = manipulability(sp, qs)
    for q, radii, d in zip(qs, m.radii, m.directions[:, 0], strict=True):
        r_min, r_max, u = ellipse_point(sp, *q)
        np.testing.assert_allclose([r_min, r_max], radii, rtol=1e-14, atol=1e-17)
        np.testing.assert_allclose(u, d, atol=1e-12)


def test_serial_guidance_continuous_joints():
    """Defect 5: kinova has continuous joints (nq = 9, nv = 6); the serial adapter steps on the
    configuration manifold and reports joint rates of size nv."""
    import pinocchio as pin

    from kinematics.model.robot import load_robot

    robot = load_robot("kinova")
    assert robot.model.nq != robot.model.nv
    kin = SerialKinematics(robot)
    bounded = np.isfinite(robot.lower)
    mid = np.full(robot.nv, 0.3)
    mid[bounded] = 0.5 * (robot.lower[bounded] + robot.upper[bounded])
    q0 = robot.configuration(mid)
    r = simulate(kin, GuidanceParams(), q0, Profile("step", (1.0, 0.0, 0.0), 5.0, 0.0), (1.0, 0.0, 0.0), 0.3)
    assert r.q.shape[1] == 9 and r.qdot.shape[1] == 6 and not r.blocked.any()
    assert r.x[-1, 0] > r.x[0, 0] + 0.01  # it moved along the push
    for q, x in zip(r.q[::50], r.x[::50], strict=True):
        np.testing.assert_allclose(kin.fk(q), x, atol=1e-6)  # the IK's own acceptance tolerance
    vals = np.array([robot.values_from_configuration(q) for q in r.q])
    assert np.all(robot.within_limits(vals))
    # joint rates: the manifold difference (not q - q_prev, which has the wrong size)
    np.testing.assert_allclose(r.qdot[10], pin.difference(robot.model, r.q[9], r.q[10]) / 1e-3, atol=1e-9)


def test_ramp_edge_cases():
    with pytest.raises(InvalidInputError, match="t1"):
        Profile("ramp", (1.0,), 3.0, 1.0)  # t1 = inf: the ramp would never rise
    with pytest.raises(InvalidInputError, match="t1"):
        Profile("pulse", (1.0,), 3.0, 2.0, 1.0)
    step = Profile("ramp", (1.0,), 3.0, 1.0, 1.0)  # t1 = t0: a step
    assert step(0.999, None) == 0.0 and step(1.0, None) == 3.0 and step(5.0, None) == 3.0
    assert Profile("step", (1.0,), 3.0, 1.0)(2.0, None) == 3.0
    with pytest.raises(InvalidInputError, match="rise"):
        ReactiveOperator((1.0, 0.0), 5.0, rise=0.0)
    with pytest.raises(InvalidInputError, match="rise"):
        StubbornOperator((1.0, 0.0), 5.0, rise=0.0)


def test_reused_operator_gives_the_same_run(sp):
    """A ReactiveOperator remembers when it let go; re-used for a second run (from a start
    farther from the wall) it must push like a fresh one, not let go at the first run's time."""
    from kinematics.mechanisms.scara.closed_form import ik

    near, far = (ik(sp, np.array([x, 0.0])).q[0] for x in (0.62, 0.4))
    kin, p = ScaraKinematics(sp), GuidanceParams()
    op = ReactiveOperator((1.0, 0.0), 6.0, feel=125.0)
    simulate(kin, p, near, op, (1.0, 0.0), 4.0)
    again = simulate(kin, p, far, op, (1.0, 0.0), 4.0)
    fresh = simulate(kin, p, far, ReactiveOperator((1.0, 0.0), 6.0, feel=125.0), (1.0, 0.0), 4.0)
    assert fresh.force.max() > 5.9
    np.testing.assert_array_equal(again.force, fresh.force)
    np.testing.assert_array_equal(again.x, fresh.x)


def test_no_branch_change_from_random_starts(sp, rng):
    """Property behind defect 1: from 100 seeded starts across the joint space (|theta2| > 0.3),
    hard pushes in random directions for 300 steps never change the elbow's sign; the elbows
    only meet at theta2 = 0, which |theta2| > 0.05 throughout rules out here."""
    kin = ScaraKinematics(sp)
    p = GuidanceParams()
    for _ in range(100):
        q0 = rng.uniform(sp.lower, sp.upper)
        if abs(q0[1]) < 0.3:
            continue
        ctrl = Controller(kin, p, q0)
        f = rng.normal(size=2)
        f *= 40.0 / np.linalg.norm(f)
        qs = np.array([ctrl.step(f).q for _ in range(300)])
        if np.abs(qs[:, 1]).min() > 0.05:
            assert np.all(np.sign(qs[:, 1]) == np.sign(q0[1]))
        assert np.all(qs >= np.array(sp.lower)) and np.all(qs <= np.array(sp.upper))


def test_an_experiment_number_given_as_text_is_refused_plainly(sp):
    """run_experiment("1", ...) said "unknown choice '1' (did you mean '1'?); valid: 1, 2, 3"."""
    from kinematics.errors import UnknownChoiceError

    with pytest.raises(InvalidInputError, match=r"is an int \(1, 2, 3\), got '1'"):
        run_experiment("1", sp)
    with pytest.raises(UnknownChoiceError, match="valid: 1, 2, 3"):
        run_experiment(9, sp)
