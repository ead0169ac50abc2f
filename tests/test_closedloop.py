"""The generic Pinocchio closed-loop solver, cross-checked against the 3-[P2(US)] closed forms."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from kinematics.errors import (
    ConvergenceError,
    InvalidInputError,
    SingularConfigurationError,
    UnsupportedRobotError,
)
from kinematics.generic.closedloop import ClosedLoop
from kinematics.mechanisms.p2us import closed_form as par
from kinematics.mechanisms.p2us.urdf import joint_values_at
from kinematics.model.robot import load_robot

from .conftest import limited_poses, sample_actuators
from .test_parallel import type_two_pose

MODELS = Path(__file__).parent / "models"


@pytest.fixture(scope="module")
def loop(p2us):
    return ClosedLoop(p2us)


def workspace_poses(P, n, rng):
    """Platform positions inside the joint-limited workspace (mode '---') and their actuators."""
    return limited_poses(par.ik, P, [-0.4, -0.4, -0.7], [0.4, 0.4, -0.1], n, rng, 200)


def test_passive_joints_match_closed_form_angles(loop, p2us, p2us_params, rng):
    # Inside the workspace the continuation from the (in-workspace) reference stays on the
    # hanging-rod branch, so the solved joints equal the closed-form angles themselves.
    P = p2us_params
    for p_expected, q in zip(*workspace_poses(P, 40, rng), strict=True):
        sol = loop.solve(q)
        p = sol.pose.translation
        assert np.linalg.norm(p - p_expected) <= 1e-9
        n = par.rod_vectors(P, p, q) / P.L
        theta, phi = par.passive_angles(P, n)
        values = dict(zip(p2us.joint_names, sol.values, strict=True))
        for i in range(3):
            for k in (1, 2):  # both rods of a parallelogram share the angles
                assert abs(values[f"u_theta_{i + 1}_{k}"] - theta[i]) <= 1e-9
                assert abs(values[f"u_phi_{i + 1}_{k}"] - phi[i]) <= 1e-9


def test_constrained_jacobian_matches_closed_form(loop, p2us_params, rng):
    P = p2us_params
    worst = 0.0
    for q in sample_actuators(P, 100, rng):
        sol = loop.solve(q)
        G = loop.constrained_jacobian(sol.q)  # platform twist per actuator rate
        jac = par.jacobians(P, sol.pose.translation, q)
        if jac.iota_II < 1e-3 or jac.iota_I < 1e-3:
            continue
        inv = np.linalg.solve(jac.Jx, np.diag(jac.Jq))  # pdot = J^-1 qdot
        worst = max(worst, np.abs(G[:3] - inv).max() / np.abs(inv).max())
        assert np.abs(G[3:]).max() <= 1e-9  # no angular velocity
    assert worst <= 1e-9


def test_warm_start_and_errors(loop, p2us_params):
    sol = loop.solve([0.3, 0.25, 0.2])
    warm = loop.solve([0.31, 0.25, 0.2], q0=sol.q)
    cold = loop.solve([0.31, 0.25, 0.2])
    assert warm.iterations < cold.iterations
    np.testing.assert_allclose(warm.pose.translation, cold.pose.translation, atol=1e-10)
    with pytest.raises(ConvergenceError, match="no assembly"):
        loop.solve([0.1, 1.5, 1.5])  # spheres cannot meet
    with pytest.raises(InvalidInputError):
        loop.solve([0.3, 0.2])
    with pytest.raises(InvalidInputError):
        loop.solve([0.3, np.nan, 0.2])
    with pytest.raises(InvalidInputError, match="Pinocchio configuration"):  # an IndexError deep inside
        loop.solve([0.31, 0.25, 0.2], q0=sol.q[:3])


def test_type_two_leaves_passive_joints_free(loop, p2us, p2us_params):
    P = p2us_params
    p, _ = type_two_pose(P)
    values = joint_values_at(P, p, "---")
    q = p2us.configuration([values[n] for n in p2us.joint_names])
    assert np.abs(loop.residual(q)[0]).max() <= 1e-12
    with pytest.raises(SingularConfigurationError):
        loop.constrained_jacobian(q)
    # continuation cannot walk onto the singularity either: a clear error, not a wrong pose
    with pytest.raises(ConvergenceError, match="singularity"):
        loop.solve([values["slider_1"], values["slider_2"], values["slider_3"]])


def test_joint_values_at_close_the_loops(loop, p2us, p2us_params, rng):
    for p, _ in zip(*workspace_poses(p2us_params, 10, rng), strict=True):
        values = joint_values_at(p2us_params, p)
        q = p2us.configuration([values[n] for n in p2us.joint_names])
        assert np.abs(loop.residual(q)[0]).max() <= 1e-12


def test_requires_a_sidecar(scara):
    with pytest.raises(UnsupportedRobotError, match="sidecar"):
        ClosedLoop(scara)


def test_generic_four_bar():
    robot = load_robot(MODELS / "fourbar.urdf")
    assert robot.loops is not None and robot.loops.mechanism is None
    cl = ClosedLoop(robot)
    g, a, c, r = 0.4, 0.1, 0.35, 0.3
    for crank in np.linspace(-np.pi, np.pi, 37):
        sol = cl.solve([crank])
        assert sol.residual <= 1e-12
        end = sol.pose.translation
        crank_tip = np.array([a * np.cos(crank), a * np.sin(crank), 0])
        assert abs(np.linalg.norm(end - crank_tip) - c) <= 1e-12
        assert abs(np.linalg.norm(end - np.array([g, 0, 0])) - r) <= 1e-12
        G = cl.constrained_jacobian(sol.q)
        h = 1e-6
        plus = cl.solve([crank + h], q0=sol.q).pose.translation
        minus = cl.solve([crank - h], q0=sol.q).pose.translation
        np.testing.assert_allclose(G[:3, 0], (plus - minus) / (2 * h), atol=1e-8)


def test_idle_freedom_is_not_a_singularity(capsys):
    """Defect 2: the RSSR's coupler spins idly between its spherical joints, so K_p always has a
    null direction, but the rocker's motion is determined by the crank. The constrained Jacobian
    must exist and match finite differences of the loop solver's poses (an independent path:
    Newton closure at crank +/- h, no Jacobian algebra). Central differences with h = 1e-6 rad:
    truncation ~h^2 |d3x| ~ 1e-13 m/rad, rounding ~ 1e-12 (closure tol) / h = 1e-6 m/rad, so
    atol 1e-5 m/rad."""
    from .test_cli import run

    robot = load_robot(MODELS / "rssr.urdf")
    cl = ClosedLoop(robot)
    h = 1e-6
    for crank in (-2.5, -0.7, 0.6, 1.9):
        sol = cl.solve([crank])
        _, K = cl.residual(sol.q)
        assert K.shape[0] < len(cl.passive_v)  # a passive freedom the loops leave free
        G = cl.constrained_jacobian(sol.q)
        plus, minus = (cl.solve([crank + s], q0=sol.q).pose for s in (h, -h))
        np.testing.assert_allclose(G[:3, 0], (plus.translation - minus.translation) / (2 * h), atol=1e-5)
        w = pin.log3(plus.rotation @ minus.rotation.T) / (2 * h)
        np.testing.assert_allclose(G[3:, 0], w, atol=1e-5)
    code, out, err = run(capsys, "jacobian", str(MODELS / "rssr.urdf"), "--q", "0.6")
    assert code == 0 and err == "" and "twist" in out


@pytest.mark.parametrize("name", ["p2us", "delta"])
def test_every_working_modes_joint_values_and_velocity_hold_in_pinocchio(name):
    """Through the `Mechanism` interface, in every working mode met (the tests above follow the
    continuation from the reference, mode '---' only): `joint_values` (closed forms) close
    every loop of the URDF in Pinocchio, and Pinocchio's constrained Jacobian there (platform
    twist per actuator rate) is the closed-form forward Jacobian `velocity(...).J`, with no
    angular velocity.

    Tolerances: the joint values are closed-form angles of O(1) rad on O(1) m links, so the loop
    residual is rounding, ~1e-15 m (measured worst 9e-16): 1e-12 as in the tests above. Both
    Jacobians are exact up to rounding amplified by the conditioning, bounded by keeping iota_I,
    iota_II >= 1e-3: 1e-9 relative as above (measured worst 6e-14; angular rows 2e-11)."""
    from kinematics.mechanisms import mechanism_of

    robot = load_robot(name)
    mech = mechanism_of(robot)
    loop = ClosedLoop(robot)
    lo, hi = mech.bounding_box("actuators")
    p = lo + (hi - lo) * np.random.default_rng(17).random((300, 3))
    res = mech.ik(p, "actuators")
    modes = set()
    for i, b in np.argwhere(res.within_limits):
        values = mech.joint_values(p[i], mech.branches[b])
        q = robot.configuration([values[n] for n in robot.joint_names])
        assert np.abs(loop.residual(q)[0]).max() <= 1e-12, (p[i], mech.branches[b])
        v = mech.velocity(p[i][None], res.q[i, b][None])
        if min(v.iota_I[0], v.iota_II[0]) < 1e-3:
            continue
        G = loop.constrained_jacobian(q)
        assert np.abs(G[:3] - v.J[0]).max() <= 1e-9 * np.abs(v.J[0]).max(), (p[i], mech.branches[b])
        assert np.abs(G[3:]).max() <= 1e-9
        modes.add(mech.branches[b])
    assert len(modes) >= (8 if name == "p2us" else 2), modes  # the modes the sample meets within the actuator ranges


def test_a_stuck_continuation_says_why_without_contradicting_itself():
    # Gepetto's five-bar (fixture) at actuated values the continuation from q = 0 cannot reach: it
    # stops where its last step closed the loops (residual ~1e-14, within the 1e-12 tolerance) but
    # jumped away from the prediction; the message said "residual 1.66e-14 > tolerance 1e-12"
    import re

    loop = ClosedLoop(load_robot(MODELS / "fivebar_gepetto" / "robot.urdf"))
    messages = []
    for target in ([-2.054303279410923, 1.824190753307169], [-2.0542932794109228, 1.824190753307169]):
        with pytest.raises(ConvergenceError) as info:
            loop.solve(np.array(target))
        messages.append(str(info.value))
        claim = re.search(r"residual (\S+) > tolerance (\S+) after", str(info.value))
        assert (claim is None) == (info.value.why is not None)
        assert claim is None or float(claim.group(1)) > float(claim.group(2))
    # the first stops on the refused jump, the second on a residual above the tolerance
    assert "a jump to another assembly, refused" in messages[0] and "> tolerance" in messages[1]
