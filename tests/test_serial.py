"""Pinocchio serial kinematics: planarity, task rows, Jacobians against finite differences."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from kinematics.errors import InvalidInputError, UnknownNameError
from kinematics.model import load_robot
from kinematics.serial import forward_kinematics, frame_jacobian, plane, task_jacobian, task_rows


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


def test_task_jacobian_selects_rows(ur5, rng):
    v = rng.uniform(ur5.lower, ur5.upper)
    q = ur5.configuration(v)
    full = frame_jacobian(ur5, q)
    np.testing.assert_array_equal(task_jacobian(ur5, q), full[:3])
    np.testing.assert_array_equal(task_jacobian(ur5, q, task="rotation"), full[3:])
    np.testing.assert_array_equal(task_jacobian(ur5, q, frame="wrist_1_link"), frame_jacobian(ur5, q, "wrist_1_link")[:3])
