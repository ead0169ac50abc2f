"""`assemble` when no closed pose exists: the error says why (which closures stay open, whether
the loops close as points or outside the ranges), on variants of the four-bar fixture built so
that the answer is known by geometry."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from kinematics.generic.assembly import AssemblyError, assemble
from kinematics.generic.closedloop import ClosedLoop
from kinematics.model.robot import load_robot

MODELS = Path(__file__).parent / "models"

SIDECAR = """format: kinematics-loops/1
end_effector: coupler_end
actuated: [crank]
closures:
  - {{name: coupler_rocker, type: {kind}, frame1: coupler_end, frame2: rocker_end}}
"""


def variant(tmp_path: Path, kind: str, urdf_edit: tuple[str, str] | None = None):
    """The four-bar (ground 0.4, crank 0.1, coupler 0.35, rocker 0.3 m) with its closure of type
    `kind`, no reference pose, and one textual edit of its URDF."""
    text = (MODELS / "fourbar.urdf").read_text()
    if urdf_edit is not None:
        assert urdf_edit[0] in text
        text = text.replace(*urdf_edit)
    (tmp_path / "fourbar.urdf").write_text(text)
    (tmp_path / "fourbar.loops.yaml").write_text(SIDECAR.format(kind=kind))
    return load_robot(tmp_path / "fourbar.urdf")


def test_a_weld_whose_frames_cannot_align_is_named_and_closes_as_a_point(tmp_path):
    # rocker_end turned a half-turn about x: the coupler's end frame is Rz(a) and the rocker's
    # Rz(b) Rx(pi), never equal (their z axes are opposite), so the 6D closure never closes while
    # the point closure (the fixture's own) does
    robot = variant(tmp_path, "6d", ('<origin xyz="0.29999999999999999 0 0"/>',
                                     '<origin xyz="0.29999999999999999 0 0" rpy="3.141592653589793 0 0"/>'))
    with pytest.raises(AssemblyError) as info:
        assemble(robot)
    msg = str(info.value)
    assert "leaves 1 of 1 closures open: coupler_rocker" in msg
    # the orientation gap of z axes held opposite: a rotation of at least pi/2 (a half-turn
    # about an axis in the xy plane is pi; the closest pose is the searcher's, so only >= pi/2)
    gap = float(re.search(r"coupler_rocker \(\S+ m, (\S+) rad\)", msg).group(1))
    assert gap >= math.pi / 2
    assert "with every closure a point (`3d`" in msg and "it closes" in msg
    assert "ignoring the joint ranges it does not close either" in msg


def test_a_loop_that_closes_only_outside_a_range_names_the_joint(tmp_path):
    # the rocker held within 0.3 rad of the ground line: its end lies 0.4 + 0.3 cos(0.3) >= 0.686 m
    # from the crank pivot, beyond the crank + coupler's 0.45 m, so no pose within the range
    # closes; without ranges the crank-rocker closes (its reference pose has rocker 1.915 rad)
    rocker = '<origin xyz="0.40000000000000002 0 0"/><axis xyz="0 0 1"/><limit lower='
    robot = variant(tmp_path, "point", (rocker + '"-3.1415926535897931" upper="3.1415926535897931"',
                                        rocker + '"-0.3" upper="0.3"'))
    with pytest.raises(AssemblyError) as info:
        assemble(robot)
    msg = str(info.value)
    gap = float(re.search(r"coupler_rocker \((\S+) m\)", msg).group(1))
    assert gap >= 0.4 + 0.3 * math.cos(0.3) - 0.45 - 1e-9
    assert "ignoring the joint ranges it closes, with rocker outside its range" in msg
    # and that pose does close (the claim checked, not only printed)
    a = assemble(robot, ranges=False)
    loop = ClosedLoop(robot)
    e, _ = loop.residual(a.q)
    assert np.max(np.abs(e)) <= 1e-10
    assert abs(a.values[robot.joint_names.index("rocker")]) > 0.3
