"""Planar or spatial, loops closed (`kinematics.generic.motion_plane`): Gepetto's iso five-bars have a
spatial tree whose closed motion is planar."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.generic.closedloop import ClosedLoop
from kinematics.generic.motion_plane import motion_plane
from kinematics.generic.serial import common_axis, plane
from kinematics.model.robot import load_robot

from .conftest import GEPETTO

needs_models = pytest.mark.skipif(not GEPETTO.is_dir(), reason=f"Gepetto's models are not at {GEPETTO}")


@needs_models
@pytest.mark.parametrize("name", ["5bar_linkage_iso3d", "5bar_linkage_iso6d"])
def test_a_spatial_tree_whose_closed_motion_is_planar(name):
    robot = load_robot(GEPETTO / name)
    assert common_axis(robot.model) is None  # the tree alone: a revolute at right angles to the others
    assert plane(robot) == (0, 2)  # the one decision: the closed motion's plane
    got = motion_plane(robot)
    assert got is not None and got.closed and got.axes == (0, 2) and got.normal == 1
    # independently of the velocity test: closed poses at random actuator values (Pinocchio's
    # closure solver from the default closed pose) keep the tip on the plane y = offset
    loop = ClosedLoop(robot)
    a0 = robot.values_from_configuration(loop.reference)[loop.actuated_dofs]
    rng = np.random.default_rng(7)
    tips = np.array([loop.solve(a0 + rng.uniform(-0.4, 0.4, 2), q0=loop.reference).pose.translation for _ in range(6)])
    # closure to 1e-10 m (the solver's tolerance) moves the tip off its plane by about as much
    np.testing.assert_allclose(tips[:, 1], got.offset, rtol=0, atol=1e-9)
    assert np.ptp(tips[:, 0]) > 1e-2 and np.ptp(tips[:, 2]) > 1e-2  # it does move, in x and z


@needs_models
def test_planar_trees_and_spatial_loops():
    five = load_robot(GEPETTO / "5bar_linkage")
    got = motion_plane(five)
    assert got is not None and not got.closed and got.axes == plane(five) == (1, 2)
    assert motion_plane(load_robot(GEPETTO / "battobot_6d")) is None  # legs: spatial


def test_a_spatial_closed_loop_is_spatial():
    assert motion_plane(load_robot("p2us")) is None
