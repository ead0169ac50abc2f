"""A closed loop with six actuators, its end effector held at a rotation: the position workspace
(constant-orientation workspace) through the batched solver, held to hand-derived answers on the
gantry6 fixture and to Pinocchio on a Gepetto leg."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from kinematics.cli.app import main
from kinematics.errors import UnsupportedRobotError
from kinematics.mechanisms import mechanism_of
from kinematics.mechanisms.orientation import ToolOrientation
from kinematics.model.robot import load_robot

from .conftest import GEPETTO

MODELS = Path(__file__).parent / "models"
RPY = (0.1, -0.2, 0.3)
OFFSET = np.array([0.05, 0.0, 0.0])  # the tool on the platform (gantry6.urdf)
BOX = (np.array([-0.1, -0.2, 0.0]), np.array([0.1, 0.2, 0.3]))  # the prismatic joints' ranges


def _pose_check(robot, rows: np.ndarray, points: np.ndarray, R: np.ndarray) -> None:
    """Pinocchio's forward kinematics of the solver's joint values: the tool at each point with
    rotation R and the closure's frames coincident (1e-9: the solver closes to 1e-12 m)."""
    tool = robot.frame_id(robot.loops.end_effector)
    c = robot.loops.closures[0]
    f1, f2 = robot.frame_id(c.frame1), robot.frame_id(c.frame2)
    for row, p in zip(rows, points, strict=True):
        q = robot.configuration(row)
        pin.framesForwardKinematics(robot.model, robot.data, q)
        np.testing.assert_allclose(robot.data.oMf[tool].translation, p, atol=1e-9)
        np.testing.assert_allclose(robot.data.oMf[tool].rotation, R, atol=1e-9)
        gap = robot.data.oMf[f1].inverse() * robot.data.oMf[f2]
        assert np.abs(pin.log6(gap).vector).max() < 1e-9


def test_gantry_joint_values_by_hand_and_by_pinocchio() -> None:
    robot = load_robot(MODELS / "gantry6.urdf")
    held = ToolOrientation.rpy(*RPY)
    mech = mechanism_of(robot, held)
    assert mech.task_axes == ("x", "y", "z")
    assert mech.batch.held and not mech.batch.translational  # its actuators do turn the tool
    rng = np.random.default_rng(3)
    R = held.matrix
    platform = BOX[0] + rng.random((40, 3)) * (BOX[1] - BOX[0])
    points = platform + R @ OFFSET
    (branch,) = [b for b in mech.branches if mech.ik(points[:1]).within_limits[0, mech.branches.index(b)]]
    rows = mech.joint_value_rows(points, branch)
    names = robot.joint_names
    # by hand: the prismatic joints carry the platform, the wrist z, y, x turns are yaw, pitch, roll
    for k, axis in enumerate(("px", "py", "pz")):
        np.testing.assert_allclose(rows[:, names.index(axis)], platform[:, k], atol=1e-9)
    for angle, joint in zip(RPY, ("rx", "ry", "rz"), strict=True):
        np.testing.assert_allclose(rows[:, names.index(joint)], angle, atol=1e-9)
    _pose_check(robot, rows, points, R)


def test_held_orientation_outside_the_wrist_range_is_empty() -> None:
    """Yaw 0.6 rad is past rz's 0.4: reached by the solver (limits ignored), inside no limit."""
    mech = mechanism_of(load_robot(MODELS / "gantry6.urdf"), ToolOrientation.rpy(0.0, 0.0, 0.6))
    p = np.array([[0.0, 0.0, 0.15]])
    ik = mech.ik(p)
    assert ik.reachable.any() and not ik.within_limits.any()


def test_refusals() -> None:
    gantry = load_robot(MODELS / "gantry6.urdf")
    with pytest.raises(UnsupportedRobotError, match="rotation"):
        mechanism_of(gantry, ToolOrientation.axis([0, 0, 1])).branches  # noqa: B018
    with pytest.raises(UnsupportedRobotError, match="exactly 6 actuators"):
        mechanism_of(load_robot(MODELS / "fourbar.urdf"), ToolOrientation.reference()).margin()
    with pytest.raises(UnsupportedRobotError, match="keeps one orientation"):
        mechanism_of(load_robot("p2us"), ToolOrientation.reference())
    with pytest.raises(UnsupportedRobotError, match="open chain"):
        mechanism_of(load_robot(MODELS / "planar3r.urdf"), ToolOrientation.reference())
    held = mechanism_of(gantry, ToolOrientation.reference())
    assert "velocity" not in held.capabilities and "margin" in held.capabilities
    with pytest.raises(UnsupportedRobotError, match="held at a rotation"):
        held.velocity(np.array([[0.05, 0.0, 0.1]]), np.zeros((1, 6)))
    with pytest.raises(UnsupportedRobotError, match="held at a rotation"):  # the solver's own Jacobians too
        held.batch.jacobians(np.array([[0.05, 0.0, 0.1]]), np.zeros((1, 12)))
    with pytest.raises(UnsupportedRobotError, match="--orientation"):  # the refusal says how
        mechanism_of(gantry).margin()


def test_cli_reference_orientation(capsys) -> None:
    """The tool held at its reference rotation (the identity): the volume is 0.2 x 0.4 x 0.3 =
    0.024 m^3 (the prismatic box shifted by the tool offset) within the error estimate, the
    rotation resolved in the report."""
    code = main(["workspace-volume", str(MODELS / "gantry6.urdf"), "--orientation", "reference", "--step", "0.1",
                 "--rtol", "0.05", "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    payload = json.loads(out)
    assert payload["orientation"]["kind"] == "rotation" and payload["orientation"]["text"].startswith("reference")
    np.testing.assert_allclose(payload["orientation"]["rotation"], np.eye(3), atol=1e-12)
    assert payload["converged"] and payload["error_estimate"] <= 0.05 * 0.024
    assert abs(payload["volume_m3"] - 0.024) <= payload["error_estimate"]


@pytest.mark.skipif(not (GEPETTO / "talos_like").exists(), reason="Gepetto models not found")
def test_gepetto_leg_foot_held_at_its_reference_rotation() -> None:
    """talos_like's foot (a frame the sidecar does not name): its reference rotation held, points
    around the reference position solved, each pose held to Pinocchio."""
    from kinematics.generic.closedloop import ClosedLoop

    robot = load_robot(GEPETTO / "talos_like", tool_frame="foot")
    mech = mechanism_of(robot, ToolOrientation.reference())
    R = mech.batch.held_orientation
    # 'reference' is the foot's rotation at the sidecar's closed reference (Pinocchio's own closure)
    loop = ClosedLoop(robot)
    q, _, _ = loop.newton(loop.reference, tol=0.0)
    pin.framesForwardKinematics(robot.model, robot.data, q)
    np.testing.assert_allclose(R, robot.data.oMf[robot.frame_id("foot")].rotation, atol=1e-12)
    p0 = mech.batch.reference_point
    points = p0 + np.array([[0.0, 0.0, 0.0], [0.02, -0.01, 0.0], [0.0, 0.02, 0.03], [-0.03, 0.0, -0.02]])
    ik = mech.ik(points)
    for b, name in enumerate(mech.branches):
        found = ik.reachable[:, b]
        if found.any():
            _pose_check(robot, mech.joint_value_rows(points[found], name), points[found], R)
    assert ik.reachable.all(axis=1).any() and ik.reachable.any(axis=1).all()


def test_fk_of_a_held_mechanism_leaves_the_held_set_out() -> None:
    """fk at a held pose's actuator values gives its point; with the wrist at zero the tool is not
    at the held rotation: no point."""
    robot = load_robot(MODELS / "gantry6.urdf")
    held = ToolOrientation.rpy(0.2, 0.1, -0.3)
    mech = mechanism_of(robot, held)
    platform = np.array([0.02, -0.05, 0.12])
    point = platform + held.matrix @ OFFSET
    q = np.array([*platform, -0.3, 0.1, 0.2])  # slides, then the wrist z, y, x: yaw, pitch, roll
    a = mech.fk(np.stack([q, np.r_[platform, 0.0, 0.0, 0.0]]))
    assert a.exists[:, 0].tolist() == [True, False]
    np.testing.assert_allclose(a.p[0, 0], point, atol=1e-9)


def test_velocity_where_no_passive_joint_moves_the_end_effector(tmp_path) -> None:
    """gantry6 with its wrist welded (three slides drive the tool, the passive chain follows): the
    Jacobians are the identity by hand, and no type II measure (+inf: no passive rate moves the
    tool; it raised an IndexError before)."""
    text = (MODELS / "gantry6.urdf").read_text()
    for joint in ("rz", "ry", "rx"):
        text = re.sub(f'(<joint name="{joint}" type=")revolute', r"\1fixed", text)
    (tmp_path / "gantry3.urdf").write_text(text)
    sidecar = (MODELS / "gantry6.loops.yaml").read_text().replace("[px, py, pz, rz, ry, rx]", "[px, py, pz]")
    (tmp_path / "gantry3.loops.yaml").write_text(sidecar)
    mech = mechanism_of(load_robot(tmp_path / "gantry3.urdf"))
    platform = np.array([[0.02, -0.05, 0.12], [-0.03, 0.1, 0.2]])
    v = mech.velocity(platform + OFFSET, platform)
    np.testing.assert_allclose(v.J, np.broadcast_to(np.eye(3), (2, 3, 3)), atol=1e-9)
    np.testing.assert_allclose(v.J_inverse, np.broadcast_to(np.eye(3), (2, 3, 3)), atol=1e-9)
    assert np.isinf(v.iota_II).all()


def test_cli_ik_with_the_tool_held(capsys) -> None:
    """`ik --orientation`: the one working mode within the limits, its actuator values the hand
    solution (slides at the target less R x the tool offset, the wrist at yaw, pitch, roll)."""
    held = ToolOrientation.rpy(*RPY)
    target = np.array([0.05, 0.1, 0.2])
    code = main(["ik", str(MODELS / "gantry6.urdf"), "--orientation", "rpy " + " ".join(map(str, RPY)), "--position",
                 *map(str, target), "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    payload = json.loads(out)
    assert payload["orientation"]["kind"] == "rotation"
    (inside,) = [s for s in payload["solutions"] if s["within_limits"]]
    np.testing.assert_allclose(inside["q"], [*(target - held.matrix @ OFFSET), RPY[2], RPY[1], RPY[0]], atol=1e-9)
