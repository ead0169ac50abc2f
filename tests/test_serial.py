"""Pinocchio serial kinematics: planarity, task rows, Jacobians against finite differences."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from kinematics.errors import InvalidInputError, UnknownNameError
from kinematics.generic.serial import forward_kinematics, frame_jacobian, plane, task_jacobian, task_rows
from kinematics.model.robot import load_robot


def test_plane_detection(scara, ur5):
    assert plane(scara) == (0, 1)
    assert plane(ur5) is None
    assert plane(load_robot("double_pendulum")) == (1, 2)  # axes along world x


def test_task_rows(scara, ur5):
    assert task_rows(scara) == (0, 1)
    assert task_rows(ur5) == (0, 1, 2)
    assert task_rows(ur5, "rotation") == (3, 4, 5)
    with pytest.raises(InvalidInputError, match="not a planar arm"):
        task_rows(ur5, "planar")
    with pytest.raises(UnknownNameError):
        task_rows(ur5, "sideways")  # type: ignore[arg-type]


def _fd_jacobian(robot, v, frame=None, h=1e-6):
    """Central differences of the frame pose: linear rows from positions, angular from log3."""
    cols = []
    for i in range(robot.nv):
        dv = np.zeros(robot.nv)
        dv[i] = h
        plus = forward_kinematics(robot, robot.configuration(v + dv), frame)
        minus = forward_kinematics(robot, robot.configuration(v - dv), frame)
        lin = (plus.position - minus.position) / (2 * h)
        ang = pin.log3(plus.rotation @ minus.rotation.T) / (2 * h)
        cols.append(np.concatenate([lin, ang]))
    return np.array(cols).T


@pytest.mark.parametrize("name", ["scara", "ur5", "panda"])
def test_frame_jacobian_matches_finite_differences(name, rng):
    robot = load_robot(name)
    for _ in range(5):
        v = rng.uniform(robot.lower, robot.upper)
        J = frame_jacobian(robot, robot.configuration(v))
        assert J.shape == (6, robot.nv)
        np.testing.assert_allclose(J, _fd_jacobian(robot, v), atol=1e-8)


def test_task_jacobian_matches_finite_differences(ur5, scara, rng):
    """The task rows against central differences of FK (not against slices of frame_jacobian,
    which is how task_jacobian is built). h = 1e-6: truncation h^2 |d3x| ~ 1e-12, rounding
    eps |x| / h ~ 1e-10 m/rad; atol 1e-8."""
    for robot, frame in ((ur5, None), (ur5, "wrist_1_link"), (scara, None)):
        v = rng.uniform(robot.lower, robot.upper)
        fd = _fd_jacobian(robot, v, frame)
        q = robot.configuration(v)
        np.testing.assert_allclose(task_jacobian(robot, q, frame), fd[list(task_rows(robot))], atol=1e-8)
        np.testing.assert_allclose(task_jacobian(robot, q, frame, task="rotation"), fd[3:], atol=1e-8)
    assert task_jacobian(scara, scara.configuration([0.1, 0.2])).shape == (2, 2)


def test_one_dof_robot(capsys):
    """Defect 6: a 1-DOF URDF (Pinocchio hands its 6 x 1 Jacobians back as 1-D arrays).
    Oracles: the pendulum's closed form, tool = (0.5 cos q, 0.5 sin q, 0.1) m."""
    from pathlib import Path

    from .test_cli import run_json

    path = Path(__file__).parent / "models" / "pendulum.urdf"
    robot = load_robot(path)
    q = 0.3
    J = frame_jacobian(robot, robot.configuration([q]))
    assert J.shape == (6, 1)
    np.testing.assert_allclose(J[:, 0], [-0.5 * np.sin(q), 0.5 * np.cos(q), 0, 0, 0, 1], atol=1e-15)
    assert plane(robot) == (0, 1)
    code, d, _ = run_json(capsys, "info", str(path))
    assert code == 0 and d["dof"] == 1
    code, d, _ = run_json(capsys, "fk", str(path), "--q", "0.3")
    assert code == 0
    np.testing.assert_allclose(d["position"][:2], [0.5 * np.cos(q), 0.5 * np.sin(q)], atol=1e-15)
    code, d, _ = run_json(capsys, "jacobian", str(path), "--q", "0.3")
    assert code == 0
    np.testing.assert_allclose(d["jacobian"], [[-0.5 * np.sin(q)], [0.5 * np.cos(q)]], atol=1e-15)
    code, d, _ = run_json(capsys, "mobility", str(path))
    assert code == 0 and d["grubler"]["mobility"] == 1 and d["numeric"]["mobility"] == 1


@pytest.mark.parametrize("q", [[0.1], [0.1, 0.2, 0.3], [[0.1, 0.2], [0.3, 0.4]], [np.nan, 0.2], [0.1, np.inf],
                               "0.1 0.2", 0.1])
def test_a_malformed_configuration_is_refused(scara, q):
    """A configuration of the wrong size, a NaN/inf or something not numbers is an InvalidInputError
    naming q (Pinocchio's C++ ValueError, a Boost ArgumentError or a NaN pose before)."""
    from kinematics.analyses.mobility import analyse

    for f in (forward_kinematics, frame_jacobian, task_jacobian, analyse):
        with pytest.raises(InvalidInputError, match="^q: "):
            f(scara, q)


def test_a_configuration_given_as_a_list_or_a_row_is_one_configuration(scara):
    q = np.array([0.3, -0.4])
    want = forward_kinematics(scara, q).position
    for given in ([0.3, -0.4], q[None]):
        np.testing.assert_array_equal(forward_kinematics(scara, given).position, want)
        np.testing.assert_array_equal(frame_jacobian(scara, given), frame_jacobian(scara, q))
