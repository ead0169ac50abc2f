"""The Gepetto robot.yaml reader: supported substitutions, what it refuses, and the CLI on it."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from kinematics.analyses import mobility as mob
from kinematics.errors import KinematicsError, KinematicsWarning, UnknownFrameError, UnknownJointError
from kinematics.generic.closedloop import ClosedLoop
from kinematics.model.gepetto import GepettoFormatError
from kinematics.model.robot import load_robot

from .test_cli import run, run_json

FIXTURE = Path(__file__).parent / "models" / "fivebar_gepetto"
GOOD = "closed_loop: [['closedloop1_A', 'closedloop1_B']]\ntype: ['6D']\nname_mot: ['mot1', 'mot2']\n"

# A spatial RSSR, closed at all-zero joint values: crank about z at the origin (0.1 m, along +y at
# zero), coupler of length L = sqrt(0.26) m from a spherical joint `s` at the crank's tip to the
# rocker's tip, rocker about y at (0.4, 0, 0) (0.3 m, along +z at zero). In the URDF `s` is a plain
# revolute; robot.yaml turns it into a spherical joint. The rpy of `s` points the coupler's x axis
# from C = (0, 0.1, 0) to T = (0.4, 0, 0.3), expressed in the crank's frame.
RSSR_URDF = """<robot name="rssr_gepetto">
  <link name="ground"/><link name="crank_link"/><link name="coupler"/><link name="coupler_end"/>
  <link name="rocker_link"/><link name="rocker_end"/>
  <joint name="crank" type="revolute"><parent link="ground"/><child link="crank_link"/>
    <origin xyz="0 0 0" rpy="0 0 1.5707963267948966"/><axis xyz="0 0 1"/>
    <limit lower="-3.14159" upper="3.14159" effort="1" velocity="1"/></joint>
  <joint name="s" type="revolute"><parent link="crank_link"/><child link="coupler"/>
    <origin xyz="0.1 0 0" rpy="0 -0.6290148024266757 -1.8157749899217608"/><axis xyz="0 0 1"/>
    <limit lower="-3.14159" upper="3.14159" effort="1" velocity="1"/></joint>
  <joint name="coupler_end_frame" type="fixed"><parent link="coupler"/><child link="coupler_end"/>
    <origin xyz="0.5099019513592785 0 0"/></joint>
  <joint name="rocker" type="revolute"><parent link="ground"/><child link="rocker_link"/>
    <origin xyz="0.4 0 0"/><axis xyz="0 1 0"/><limit lower="-3.14159" upper="3.14159" effort="1" velocity="1"/></joint>
  <joint name="rocker_end_frame" type="fixed"><parent link="rocker_link"/><child link="rocker_end"/>
    <origin xyz="0 0 0.3"/></joint>
</robot>
"""
RSSR_YAML = ("closed_loop: [['coupler_end', 'rocker_end']]\ntype: ['3D']\nname_mot: ['crank']\n"
             "joint_name: ['s']\njoint_type: ['SPHERICAL']\n")


def fivebar_with(tmp_path: Path, yaml_text: str) -> Path:
    shutil.copy(FIXTURE / "robot.urdf", tmp_path / "robot.urdf")
    (tmp_path / "robot.yaml").write_text(yaml_text)
    return tmp_path / "robot.urdf"


def test_spherical_substitution_rssr(tmp_path):
    """SPHERICAL becomes s_X, s_Y, s_Z through the joint's origin. Closed form of the rocker angle
    beta for crank angle alpha: with C = (-0.1 sin a, 0.1 cos a, 0) and T = (0.4 + 0.3 sin b, 0,
    0.3 cos b), |T - C|^2 = L^2 is linear in sin b:
    sin b = (L^2 - 0.09 - 0.01 cos^2 a - (0.4 + 0.1 sin a)^2) / (0.6 (0.4 + 0.1 sin a))."""
    (tmp_path / "rssr.urdf").write_text(RSSR_URDF)
    (tmp_path / "robot.yaml").write_text(RSSR_YAML)
    robot = load_robot(tmp_path / "rssr.urdf")
    assert robot.joint_names == ("crank", "s_X", "s_Y", "s_Z", "rocker")
    assert robot.tool_frame == "coupler_end"  # no `effector` frame: the first pair's first frame
    # the three revolutes share the origin of the URDF's joint and turn about its x, y, z axes
    data = robot.model.createData()
    q = robot.configuration([0.3, 0.2, -0.4, 0.5, 0.0])
    pin.forwardKinematics(robot.model, data, q)
    origins = [data.oMi[robot.model.getJointId(n)].translation for n in ("s_X", "s_Y", "s_Z")]
    np.testing.assert_allclose(origins[1], origins[0], atol=1e-15)
    np.testing.assert_allclose(origins[2], origins[0], atol=1e-15)
    loop = ClosedLoop(robot)
    L2 = 0.26
    for alpha in (-0.6, -0.2, 0.25, 0.7):
        sol = loop.solve([alpha])
        assert sol.residual <= 1e-12
        k = 0.4 + 0.1 * np.sin(alpha)
        beta = np.arcsin((L2 - 0.09 - 0.01 * np.cos(alpha) ** 2 - k**2) / (0.6 * k))  # branch of beta = 0
        # 1e-10: closure error 1e-12 m over a rocker lever of 0.3 m with a well-conditioned crossing
        assert abs(sol.values[robot.joint_names.index("rocker")] - beta) <= 1e-10
    robot = load_robot(tmp_path / "rssr.urdf", tool_frame="rocker_end")  # the rocker as the output
    rep = mob.analyse(robot, loop.solve([0.25]).q)
    assert rep.grubler.as_dict()["joint_types"] == {"R": 2, "S": 2}  # the substituted S and the 3D closure
    assert rep.grubler.mobility == 2 and rep.numeric.mobility == 2 and rep.numeric.idle == 1  # coupler spin


@pytest.mark.parametrize(("kind", "names"), [("UJOINT_XY", ("s_X", "s_Y")), ("UJOINT_YZ", ("s_Y", "s_Z")),
                                             ("UJOINT_ZX", ("s_Z", "s_X")), ("UJOINT_ZY", ("s_Z", "s_Y")),
                                             ("UJOINT_XZ", ("s_X", "s_Z")), ("UJOINT_YX", ("s_Y", "s_X")),
                                             ("CARDAN", ("s_X", "s_Y"))])
def test_universal_joint_substitutions(tmp_path, kind, names):
    (tmp_path / "rssr.urdf").write_text(RSSR_URDF)
    (tmp_path / "robot.yaml").write_text(RSSR_YAML.replace("SPHERICAL", kind))
    robot = load_robot(tmp_path / "rssr.urdf")
    assert robot.joint_names == ("crank", *names, "rocker")
    axes = {"X": [1, 0, 0], "Y": [0, 1, 0], "Z": [0, 0, 1]}
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, pin.neutral(robot.model))
    for n in names:  # each revolute turns about its named axis of the URDF joint's frame
        jid = robot.model.getJointId(n)
        J = pin.computeJointJacobian(robot.model, data, pin.neutral(robot.model), jid)
        np.testing.assert_allclose(J[3:, robot.model.joints[jid].idx_v], axes[n[-1]], atol=1e-15)


def test_not_gepetto_yaml_is_ignored_and_own_sidecar_wins(tmp_path):
    path = fivebar_with(tmp_path, "some_tool_setting: 3\n")
    assert load_robot(path).loops is None
    (tmp_path / "robot.yaml").write_text(GOOD)
    (tmp_path / "robot.loops.yaml").write_text(
        "end_effector: effector\nactuated: [mot1, mot2]\n"
        "closures:\n  - {type: point, frame1: closedloop1_A, frame2: closedloop3D_B}\n")
    assert load_robot(path).loops.path.name == "robot.loops.yaml"


def test_tool_frame_becomes_the_end_effector(tmp_path):
    robot = load_robot(fivebar_with(tmp_path, GOOD), tool_frame="closedloop1_B")
    assert robot.loops.end_effector == "closedloop1_B"


@pytest.mark.parametrize(("text", "error", "match"), [
    ("name_mot: mot\nname_closedloop: fermeture\nclosed_loop_number: 1\ntype: 6D\n", GepettoFormatError,
     "name-pattern form"),
    (GOOD + "effector: x\n", GepettoFormatError, "unknown key.*'effector'.*valid: closed_loop"),
    ("closed_loop: [['closedloop1_A', 'closedloop1_B']]\n", GepettoFormatError, "name_mot: missing"),
    (GOOD.replace("6D", "4D"), GepettoFormatError, "type: unsupported closure type '4D'; valid: 3D, 6D"),
    (GOOD.replace("['6D']", "['6D', '3D']"), GepettoFormatError, "type: 2 type.*for 1 closed_loop"),
    ("closed_loop: [['closedloop1_A']]\nname_mot: [mot1]\n", GepettoFormatError, "closed_loop: expected a list"),
    (GOOD + "joint_name: [free3]\njoint_type: [PLANAR]\n", GepettoFormatError,
     "unsupported joint type 'PLANAR'; valid: SPHERICAL"),
    (GOOD + "joint_name: [free3, free2]\njoint_type: [FIXED]\n", GepettoFormatError, "1 joint_type.*for 2"),
    (GOOD + "joint_name: [mot2]\njoint_type: [FIXED]\n", GepettoFormatError, "motor 'mot2' is substituted"),
    (GOOD + "joint_name: [closedloop1_A_frame]\njoint_type: [SPHERICAL]\n", GepettoFormatError,
     "fixed joint in the URDF"),
    (GOOD.replace("closedloop1_B", "nowhere"), UnknownFrameError, "unknown frame 'nowhere'"),
    (GOOD.replace("'mot2'", "'motor_2'"), UnknownJointError,
     r"unknown joint 'motor_2' \(did you mean 'mot2'\?\); valid: mot1"),
    (GOOD.replace("closedloop1_B", "free3") + "joint_name: [free3]\njoint_type: [SPHERICAL]\n",
     GepettoFormatError, "names 'free3', the frame of a joint substituted by SPHERICAL"),
    ("closed_loop: [[a, b]\n", GepettoFormatError, "malformed YAML"),
])
def test_refusals(tmp_path, capsys, text, error, match):
    path = fivebar_with(tmp_path, text)
    with pytest.raises(error, match=match) as info:
        load_robot(path)
    assert isinstance(info.value, KinematicsError)
    code, out, err = run(capsys, "info", str(path))
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_a_robot_yaml_that_is_not_text_is_refused(tmp_path):
    path = fivebar_with(tmp_path, "")
    (tmp_path / "robot.yaml").write_bytes(b"\xff\xfe not text")  # a UnicodeDecodeError traceback
    with pytest.raises(GepettoFormatError, match="not UTF-8 text"):
        load_robot(path)


def test_a_substitution_of_an_unknown_joint_is_left_out_with_a_warning(tmp_path, capsys):
    # as Gepetto's loader: the other substitution applies, the unknown name is skipped, loudly
    path = fivebar_with(tmp_path, GOOD + "joint_name: [free_2, free3]\njoint_type: [SPHERICAL, SPHERICAL]\n")
    with pytest.warns(KinematicsWarning, match="'free_2', which the URDF does not have \\(did you mean 'free2'"):
        robot = load_robot(path)
    assert "free2" in robot.joint_names and "free3_X" in robot.joint_names
    code, out, err = run(capsys, "info", str(path))
    assert code == 0 and err.startswith("kinematics info: warning: ") and len(err.strip().splitlines()) == 1


def test_cli_on_the_fixture(capsys):
    path = str(FIXTURE / "robot.urdf")
    code, data, err = run_json(capsys, "info", path)
    assert code == 0 and data["loops"]["constraints"][0]["type"] == "6d"
    assert data["loops"]["sidecar"].endswith("robot.yaml")
    code, data, err = run_json(capsys, "mobility", path)
    assert code == 0 and data["numeric"]["mobility"] == 2 and data["grubler"]["mobility"] == 2
    for command in ("fk", "jacobian"):
        code, out, err = run(capsys, command, path, "--q", "0.1", "-0.2")
        assert code == 0 and err == "" and out
    code, out, err = run(capsys, "fk", path, "--q", "0.1")
    assert code == 2 and len(err.strip().splitlines()) == 1


def _lens(r1: float, r2: float, d: float) -> float:
    """Area [m^2] of the intersection of two discs of radii r1, r2 whose centres are d apart."""
    if d >= r1 + r2:
        return 0.0
    if d <= abs(r1 - r2):
        return float(np.pi * min(r1, r2) ** 2)
    a1 = r1**2 * np.arccos((d * d + r1 * r1 - r2 * r2) / (2 * d * r1))
    a2 = r2**2 * np.arccos((d * d + r2 * r2 - r1 * r1) / (2 * d * r2))
    return float(a1 + a2 - 0.5 * np.sqrt((-d + r1 + r2) * (d + r1 - r2) * (d - r1 + r2) * (d + r1 + r2)))


def test_cli_workspace_area_of_the_planar_fixture(capsys, tmp_path):
    """`workspace-volume` on a planar closed loop: the five-bar's joints span full turns, so every
    working mode's workspace is where both chains reach, the intersection of the annuli
    |a_i - b_i| <= |P - A_i| <= a_i + b_i; its area (discs by inclusion-exclusion, each small disc
    inside its large one) must lie within the reported error estimate. Its singular points and a
    planar plot come with it."""
    from .fivebar import FiveBar

    five = FiveBar.from_robot(load_robot(FIXTURE / "robot.urdf"))
    d = float(np.linalg.norm(five.A[1] - five.A[0]))
    outer, inner = five.a + five.b, np.abs(five.a - five.b)
    exact = (_lens(outer[0], outer[1], d) - _lens(outer[0], inner[1], d) - _lens(inner[0], outer[1], d)
             + _lens(inner[0], inner[1], d))
    plot = tmp_path / "ws.png"
    code, data, err = run_json(capsys, "workspace-volume", str(FIXTURE / "robot.urdf"), "--step", "0.05",
                               "--rtol", "5e-2", "--modes", "++", "--plot", str(plot))
    assert code == 0 and data["converged"] and set(data["modes"]) == {"++"}  # working modes, not a SCARA's elbows
    assert abs(data["area_m2"] - exact) <= data["error_estimate"], (data["area_m2"], exact)
    assert data["singularities"]["type_II"]["inside_workspace"] > 0  # the distal links align inside
    assert all(len(p["position"]) == 2 for p in data["singular_points"])
    assert plot.stat().st_size > 10_000
