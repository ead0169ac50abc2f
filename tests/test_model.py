"""Model loading, validation errors and the two-parser agreement."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinematics.errors import (
    InvalidInputError,
    KinematicsError,
    ModelFileError,
    UnknownFrameError,
    UnknownRobotError,
)
from kinematics.model.robot import load_robot, parser_agreement, robot_names


def test_builtin_scara_joints_and_limits(scara):
    assert scara.joint_names == ("joint1", "joint2")
    assert scara.tool_frame == "tool"
    assert scara.lower == pytest.approx([-math.radians(110), -math.radians(130)], abs=1e-15)
    assert scara.upper == pytest.approx([math.radians(110), math.radians(130)], abs=1e-15)


def test_load_by_path_and_example_robot_data(scara, ur5):
    by_path = load_robot(scara.urdf_path)
    assert by_path.joint_names == scara.joint_names
    assert ur5.nv == 6 and ur5.tool_frame == "tool0"
    assert "ur5" in robot_names() and "scara" in robot_names()


def test_unknown_robot_lists_valid_names():
    with pytest.raises(UnknownRobotError) as info:
        load_robot("no_such_robot")
    assert "scara" in info.value.valid and "ur5" in info.value.valid
    assert "scara" in str(info.value)


def test_missing_file(tmp_path):
    with pytest.raises(ModelFileError, match="no such file"):
        load_robot(tmp_path / "absent.urdf")


def test_malformed_xml(tmp_path):
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'></robot>")
    with pytest.raises(ModelFileError, match="malformed XML"):
        load_robot(bad)


def test_not_a_urdf(tmp_path):
    bad = tmp_path / "notrobot.urdf"
    bad.write_text("<sdf version='1.6'/>")
    with pytest.raises(ModelFileError, match="root element is <sdf>"):
        load_robot(bad)


def test_urdf_pinocchio_rejects(tmp_path, capfd):
    bad = tmp_path / "dangling.urdf"
    bad.write_text(
        "<robot name='x'><link name='a'/><joint name='j' type='revolute'><parent link='a'/>"
        "<child link='missing'/><axis xyz='0 0 1'/><limit lower='-1' upper='1' effort='1' velocity='1'/>"
        "</joint></robot>"
    )
    with pytest.raises(ModelFileError, match="Pinocchio cannot parse"):
        load_robot(bad)
    assert capfd.readouterr().err == ""  # urdfdom's own stderr output is captured into the error


def test_unknown_frame_lists_frames(scara):
    with pytest.raises(UnknownFrameError) as info:
        scara.frame_id("nope")
    assert "tool" in info.value.valid
    with pytest.raises(UnknownFrameError):
        load_robot("scara", tool_frame="nope")


@pytest.mark.parametrize("values", [[0.1], [0.1, 0.2, 0.3], []])
def test_wrong_number_of_joint_values(scara, values):
    with pytest.raises(InvalidInputError, match="2 degrees of freedom"):
        scara.joint_values(values)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_joint_values(scara, bad):
    with pytest.raises(InvalidInputError, match="finite"):
        scara.configuration([0.1, bad])


@pytest.mark.parametrize("pair", [1.0, (0.0, 1.0, 2.0), ("a", "b"), None, (1.0, 0.0), (math.nan, 1.0)])
def test_a_range_that_is_no_pair_of_numbers_is_refused(pair):
    """load_robot(ranges=...) names the joint and the pair for anything but finite LO < HI (a
    number, a triple or text was a TypeError or ValueError from the unpacking)."""
    with pytest.raises(InvalidInputError, match="range of joint1"):
        load_robot("scara", ranges={"joint1": pair})


def test_errors_share_one_root():
    for cls in (InvalidInputError, ModelFileError, UnknownFrameError, UnknownRobotError):
        assert issubclass(cls, KinematicsError)


def test_degrees_convert_revolute_only(tmp_path):
    urdf = tmp_path / "rp.urdf"
    urdf.write_text(
        "<robot name='rp'><link name='a'/><link name='b'/><link name='c'/>"
        "<joint name='r' type='revolute'><parent link='a'/><child link='b'/><axis xyz='0 0 1'/>"
        "<limit lower='-3' upper='3' effort='1' velocity='1'/></joint>"
        "<joint name='p' type='prismatic'><parent link='b'/><child link='c'/><axis xyz='1 0 0'/>"
        "<limit lower='0' upper='1' effort='1' velocity='1'/></joint></robot>"
    )
    robot = load_robot(urdf)
    assert [d.kind for d in robot.dofs] == ["revolute", "prismatic"]
    assert robot.joint_values([90.0, 0.5], degrees=True) == pytest.approx([math.pi / 2, 0.5])


def test_an_empty_range_reads_as_no_range(tmp_path, capsys):
    """lower = upper (example-robot-data's double_pendulum writes lower="0" upper="0") is the
    URDF's placeholder for "no range", never a joint that cannot move; a workspace asks for it."""
    from kinematics.cli import main

    urdf = tmp_path / "rr.urdf"
    urdf.write_text(
        "<robot name='rr'><link name='a'/><link name='b'/><link name='c'/>"
        "<joint name='r1' type='revolute'><parent link='a'/><child link='b'/><axis xyz='0 0 1'/>"
        "<limit lower='0' upper='0' effort='0' velocity='0'/></joint>"
        "<joint name='r2' type='revolute'><parent link='b'/><child link='c'/><origin xyz='1 0 0'/>"
        "<axis xyz='0 0 1'/><limit lower='-1' upper='1' effort='1' velocity='1'/></joint></robot>"
    )
    robot = load_robot(urdf)
    assert [d.range_given for d in robot.dofs] == [False, True]
    assert robot.dofs[0].lower == -math.inf and robot.dofs[0].upper == math.inf
    assert main(["workspace-volume", str(urdf), "--rtol", "1e-2"]) == 2
    assert "--range r1=LO:HI" in capsys.readouterr().err


@pytest.mark.parametrize(("text", "expected"), [
    ("joint1=-pi/2:3pi/4", (-0.5 * math.pi, 0.75 * math.pi)),
    ("joint1=-pi:pi", (-math.pi, math.pi)),
    ("joint1=0.25:2*pi", (0.25, 2.0 * math.pi)),
    ("joint1=-.5pi:1e-1", (-0.5 * math.pi, 0.1)),
])
def test_range_flag_takes_multiples_of_pi(text, expected, capsys):
    """`--range` reads LO and HI as numbers or multiples of pi (the Gepetto models' actuators are
    given -pi:pi in docs/models.md); the JSON report shows the range read (to the last bit)."""
    import json

    from kinematics.cli import main

    assert main(["info", "scara", "--range", text, "--json"]) == 0
    joint = json.loads(capsys.readouterr().out)["joints"][0]
    assert (joint["lower"], joint["upper"]) == expected


@pytest.mark.parametrize("text", ["joint1=-pi:pix", "joint1=pi/0:1", "joint1=.pi:1", "joint1=pi:-pi"])
def test_range_flag_refuses_what_is_no_angle(text, capsys):
    from kinematics.cli import main

    assert main(["info", "scara", "--range", text]) == 2
    assert "expected JOINT=LO:HI with finite LO < HI" in capsys.readouterr().err


def test_continuous_joints_round_trip(rng):
    kinova = load_robot("kinova")
    assert any(d.kind == "continuous" for d in kinova.dofs)
    v = rng.uniform(-3, 3, kinova.nv)
    assert kinova.values_from_configuration(kinova.configuration(v)) == pytest.approx(v, abs=1e-14)


@pytest.mark.parametrize("name", ["scara", "ur5", "panda", "kinova"])
def test_pinocchio_and_yourdfpy_agree(name, rng):
    robot = load_robot(name)
    lo = np.where(np.isfinite(robot.lower), robot.lower, -np.pi)
    hi = np.where(np.isfinite(robot.upper), robot.upper, np.pi)
    for values in (None, rng.uniform(lo, hi)):
        agree = parser_agreement(robot, values)
        assert agree.frames >= 4
        assert agree.max_position_error <= 1e-12
        assert agree.max_rotation_error <= 1e-12


def test_default_tool_frame_of_a_tree_is_moved_by_joints(tmp_path):
    """The tool frame defaults to the last link, unless no joint moves it (a sensor fixed to the
    base written last, as tiago's URDF does): then the last link of the chain with the most
    moving joints (here the 2-joint arm's tip, not the 1-joint branch or the sensor)."""
    joint = ("<joint name='{n}' type='revolute'><parent link='{p}'/><child link='{c}'/><axis xyz='0 0 1'/>"
             "<limit lower='-1' upper='1' effort='1' velocity='1'/></joint>")
    links = "".join(f"<link name='{n}'/>" for n in ("base", "a1", "a2", "tip", "b1", "laser"))
    urdf = tmp_path / "tree.urdf"
    urdf.write_text(
        f"<robot name='tree'>{links}"
        + joint.format(n="j1", p="base", c="a1") + joint.format(n="j2", p="a1", c="a2")
        + "<joint name='tip_joint' type='fixed'><parent link='a2'/><child link='tip'/></joint>"
        + joint.format(n="k1", p="base", c="b1")
        + "<joint name='laser_joint' type='fixed'><parent link='base'/><child link='laser'/></joint></robot>")
    assert load_robot(urdf).tool_frame == "tip"
    # the last link moved by a joint stays the default, however short its chain
    urdf.write_text(urdf.read_text().replace(
        "<joint name='laser_joint' type='fixed'><parent link='base'/>",
        "<joint name='laser_joint' type='fixed'><parent link='b1'/>"))
    assert load_robot(urdf).tool_frame == "laser"


@pytest.mark.parametrize("spec", [3, None, b"scara", ["scara"]])
def test_load_robot_refuses_what_is_no_name_or_path(spec):
    # each was a TypeError from os.fspath ("expected str, bytes or os.PathLike object, not int")
    from kinematics.errors import InvalidInputError

    with pytest.raises(InvalidInputError, match="expected a name, a URDF path or a model folder"):
        load_robot(spec)
