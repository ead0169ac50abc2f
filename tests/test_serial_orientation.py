"""The reachable set with a fixed tool orientation (issue 29, item 3b): `workspace-volume
--orientation / --tool-axis` against volumes derived by hand for arms built here."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from kinematics.analyses.workspace import measure_workspace
from kinematics.errors import InvalidInputError, UnsupportedRobotError
from kinematics.generic.batched import batched_fk, configurations
from kinematics.mechanisms import mechanism_of
from kinematics.mechanisms.orientation import ToolOrientation
from kinematics.mechanisms.serial.mechanism import with_fixed_orientation
from kinematics.model.robot import load_robot
from tests.test_serial_workspace import revolved_volume_closed_form

MODELS = Path(__file__).parent / "models"
A1, A2 = 0.3, 0.2  # tests/models/planar3r.urdf: the first two links [m]; the elbow in [0.3, 2.5] rad


def planar_fixed_orientation_area() -> float:
    """The planar 3R arm with its end orientation phi fixed: the wrist point w = p - a3 (cos phi,
    sin phi) must be a 2R point, |w| = r(e) with r(e)^2 = A1^2 + A2^2 + 2 A1 A2 cos e, e in
    [0.3, 2.5] (r decreasing in e), at any azimuth (full-turn shoulder); the full-turn wrist then
    gives phi. The set is the annulus r(2.5) <= |w| <= r(0.3) shifted by a3 (cos phi, sin phi):
    area pi (r(0.3)^2 - r(2.5)^2) = 2 pi A1 A2 (cos 0.3 - cos 2.5), whatever phi."""
    return 2 * math.pi * A1 * A2 * (math.cos(0.3) - math.cos(2.5))


@pytest.mark.parametrize(("orientation", "rtol"), [(ToolOrientation.rpy(0.0, math.pi / 2, 0.7), 1e-5),
                                                   (ToolOrientation.axis([math.cos(0.7), math.sin(0.7), 0.0]), 1e-4)],
                         ids=["rpy", "axis"])
def test_planar_3r_fixed_orientation_area(orientation, rtol):
    """The tool frame's z axis runs along the last link (rpy 0 pi/2 0 in the URDF), so both forms
    fix phi = 0.7: the same annulus."""
    exact = planar_fixed_orientation_area()  # 0.662177 m^2
    arm = with_fixed_orientation(load_robot(MODELS / "planar3r.urdf"), orientation)
    ws = measure_workspace(arm, step=0.01, rtol=rtol, check=True)
    assert ws.planar and ws.result.converged
    assert abs(ws.total - exact) <= ws.error <= 2 * rtol * exact


def test_planar_3r_margin_sign_is_membership():
    """At random plane points the margin's sign is the annulus's membership (points within 1e-9 m
    of its circles left out: the sign there is the search tolerance's)."""
    orientation = ToolOrientation.axis([math.cos(0.7), math.sin(0.7), 0.0])
    arm = with_fixed_orientation(load_robot(MODELS / "planar3r.urdf"), orientation)
    rng = np.random.default_rng(11)
    p = rng.uniform(-0.6, 0.6, (20000, 2))
    w = np.hypot(*(p - 0.1 * np.array([math.cos(0.7), math.sin(0.7)])).T)

    def r(e: float) -> float:
        return math.sqrt(A1**2 + A2**2 + 2 * A1 * A2 * math.cos(e))

    inside = (w >= r(2.5)) & (w <= r(0.3))
    clear = np.minimum(np.abs(w - r(2.5)), np.abs(w - r(0.3))) > 1e-9
    m = arm.margin()(p)[:, 0]
    np.testing.assert_array_equal((m >= 0)[clear], inside[clear])


def test_wrist_arm_tool_down_is_the_3r_volume():
    """tests/models/arm4r_wrist.urdf: the 3R arm of arm3r_revolved.urdf with a full-turn wrist pitch
    and a 0.1 m tool whose z axis lies along it. With the tool axis pointing down the wrist centre is
    0.1 m above the tool point and may be any point of the 3R arm's workspace (the wrist turns the
    last link down from any forearm direction), so the volume is the 3R arm's closed form; a tool
    axis along the base axis keeps the set a solid of revolution (measured by its profile)."""
    exact = revolved_volume_closed_form(-0.5, 0.8, 0.3, 1.5)  # 0.331334 m^3
    robot = load_robot(MODELS / "arm4r_wrist.urdf")
    arm = with_fixed_orientation(robot, ToolOrientation.axis([0.0, 0.0, -2.0]))
    assert arm.reach.setup.mode == "revolved"
    ws = measure_workspace(arm, step=0.01, rtol=1e-4, check=True)
    assert abs(ws.total - exact) <= ws.error <= 2e-4 * exact
    # The derivation's premise, checked by forward kinematics: with the wrist set to bring the last
    # link down (pitch + elbow + wrist = pi/2), the tool sits 0.1 m below the 3R arm's tip.
    rng = np.random.default_rng(2)
    v = rng.uniform([-math.pi, -0.5, 0.3, 0.0], [math.pi, 0.8, 1.5, 0.0], (200, 4))
    v[:, 3] = math.pi / 2 - v[:, 1] - v[:, 2]
    tip3 = batched_fk(load_robot(MODELS / "arm3r_revolved.urdf"), configurations(
        load_robot(MODELS / "arm3r_revolved.urdf"), v[:, :3]), "tip").position
    pose = batched_fk(robot, configurations(robot, v), "tip")
    np.testing.assert_allclose(pose.position, tip3 - [0, 0, 0.1], atol=1e-12)
    np.testing.assert_allclose(pose.rotation[:, :, 2], np.tile([0, 0, -1.0], (200, 1)), atol=1e-12)


def test_a_tilted_axis_is_measured_in_space():
    """A tool axis off the base axis is not invariant under the base's turn: no solid of revolution."""
    arm = with_fixed_orientation(load_robot(MODELS / "arm4r_wrist.urdf"), ToolOrientation.axis([1.0, 0.0, -1.0]))
    assert arm.reach.setup.mode == "spatial"


def test_orientation_parsing_and_bad_input(tmp_path):
    o = ToolOrientation.parse("rpy 0.1, 0.2, 0.3")
    assert o.kind == "rotation"
    from scipy.spatial.transform import Rotation

    Rz, Ry, Rx = (Rotation.from_rotvec(a * np.eye(3)[k]).as_matrix() for k, a in ((2, 0.3), (1, 0.2), (0, 0.1)))
    np.testing.assert_allclose(o.matrix, Rz @ Ry @ Rx, atol=1e-15)  # URDF's rpy: extrinsic x, y, z
    np.testing.assert_allclose(ToolOrientation.parse("axis 0 0 -3").matrix[:, 2], [0, 0, -1])
    for bad in ("rpy 1 2", "quat 1 0 0 0", "rpy a b c", "axis 0 0 0"):
        with pytest.raises(InvalidInputError):
            ToolOrientation.parse(bad)
    with pytest.raises(UnsupportedRobotError, match="loop"):
        with_fixed_orientation(load_robot("p2us"), o)
    with pytest.raises(UnsupportedRobotError, match="keeps one orientation"):  # a closed loop's platform: the dispatch
        mechanism_of(load_robot("p2us"), o)
    assert mechanism_of(load_robot(MODELS / "planar3r.urdf"), o).orientation is o


def test_cli_tool_axis_and_dexterity_cells(capsys, tmp_path):
    """`workspace-volume --tool-axis` reports the orientation and the annulus's area; `dexterity
    --cells --cells-out` writes the per-cell table the JSON carries; `dexterity --tool-axis` the
    mean Yoshikawa index with the orientation held."""
    from tests.test_cli import run, run_json

    code, d, _ = run_json(capsys, "workspace-volume", str(MODELS / "planar3r.urdf"), "--tool-axis",
                          str(math.cos(0.7)), str(math.sin(0.7)), "0", "--rtol", "1e-3")
    assert code == 0
    assert d["orientation"]["kind"] == "axis" and d["parameters"]["orientation"]["kind"] == "axis"
    assert abs(d["area_m2"] - planar_fixed_orientation_area()) <= d["error_estimate"]
    code, _, err = run(capsys, "workspace-volume", "p2us", "--tool-axis", "0", "0", "-1")
    assert code == 2 and "keeps one orientation" in err
    csv = tmp_path / "cells.csv"
    code, d, _ = run_json(capsys, "dexterity", str(MODELS / "planar3r.urdf"), "--samples", "1024", "--cells", "4",
                          "--cells-out", str(csv))
    assert code == 0 and d["target"] == "union" and d["smallest_radius_unit"] == "m/rad"
    rows = d["cells"]["rows"]
    lines = csv.read_text().splitlines()
    assert len(lines) == len(rows) + 1 and lines[0].startswith("index_0,index_1,lower_0")
    assert float(lines[1].split(",")[lines[0].split(",").index("area_m2")]) == rows[0]["area_m2"]
    code, _, err = run(capsys, "dexterity", str(MODELS / "planar3r.urdf"), "--cells-out", str(csv))
    assert code == 2 and "--cells" in err
    # dexterity with phi held: w = A1 A2 |sin e| / sqrt(3) (test_planar_3r_fixed_orientation_jacobian)
    # averaged over the annulus, whose area element is A1 A2 sin e de dtheta:
    # mean w = A1 A2 / sqrt(3) x int sin^2 e de / int sin e de over [0.3, 2.5]
    code, d, _ = run_json(capsys, "dexterity", str(MODELS / "planar3r.urdf"), "--samples", "1024", "--replicates",
                          "4", "--tool-axis", str(math.cos(0.7)), str(math.sin(0.7)), "0")
    sin2 = 1.1 - (math.sin(5.0) - math.sin(0.6)) / 4
    exact = A1 * A2 / math.sqrt(3) * sin2 / (math.cos(0.3) - math.cos(2.5))  # 0.029206 m^2/rad^2
    assert code == 0 and d["orientation"]["kind"] == "axis"
    assert abs(d["yoshikawa_mean"] - exact) <= d["yoshikawa_error"]


def test_ur5_rotation_and_axis_agree(monkeypatch):
    """The UR5's wrist 3 turns a full turn about the tool's z axis, so the tool held at rpy (pi, 0, 0)
    (z down, x along +x) reaches the same positions as the tool z axis held down: the rotation is
    reduced to that axis (`orientation.reduced`: on the base's profile, wrist 3 held), and the
    search without the reduction (in space with two tool vectors and six joints) gives the same
    sign at random points, but for a few near the boundary where one search stops short (at most
    0.2 %)."""
    from kinematics.mechanisms.serial import reach as reach_module

    robot = load_robot("ur5")
    rot = with_fixed_orientation(robot, ToolOrientation.rpy(math.pi, 0.0, 0.0))
    assert rot.reach.orientation is not None and rot.reach.orientation.kind == "axis"
    assert rot.reach.setup.mode == "revolved" and rot.reach.setup.fixed == ("wrist_3_joint",)
    assert not rot.reach.searched[-1]
    monkeypatch.setattr(reach_module, "reduced", lambda robot, kin, orientation, tol, reach: orientation)
    full = with_fixed_orientation(robot, ToolOrientation.rpy(math.pi, 0.0, 0.0))
    assert full.reach.setup.mode == "spatial" and full.reach.searched.all()
    lo, hi = full.bounding_box()
    p = lo + (hi - lo) * np.random.default_rng(4).random((8000, 3))
    a, b = full.margin()(p)[:, 0] >= 0, rot.margin()(p)[:, 0] >= 0
    assert a.sum() > 1000  # (about 19 % of the reach ball's box)
    assert (a != b).mean() <= 2e-3


def test_planar_3r_fixed_orientation_jacobian():
    """With the end orientation phi held, the joint velocities that keep it are dq1 + dq2 + dq3 = 0,
    and the point moves with the wrist point w = p - a3 (cos phi, sin phi): dp = J_2R (dq1, dq2).
    In an orthonormal basis of that plane (its projection on (dq1, dq2) scales areas by 1/sqrt(3),
    the plane's normal (1, 1, 1) / sqrt(3)), sqrt(det(J J^T)) = A1 A2 |sin e| / sqrt(3), e the
    elbow of w (cos e = (|w|^2 - A1^2 - A2^2) / (2 A1 A2)); to 1e-9 (the solutions reach within 1e-10 m)."""
    arm = with_fixed_orientation(load_robot(MODELS / "planar3r.urdf"),
                                 ToolOrientation.axis([math.cos(0.7), math.sin(0.7), 0.0]))
    rng = np.random.default_rng(5)
    p = rng.uniform(-0.6, 0.6, (400, 2))
    J, ok = arm.reaching_jacobians(p)
    assert ok[:, 0].sum() > 50
    w = p - 0.1 * np.array([math.cos(0.7), math.sin(0.7)])
    cos_e = (np.sum(w**2, axis=1) - A1**2 - A2**2) / (2 * A1 * A2)
    expected = A1 * A2 * np.sqrt(np.clip(1 - cos_e**2, 0.0, None)) / math.sqrt(3)
    Jok = J[ok]
    got = np.sqrt(np.abs(np.linalg.det(Jok @ np.swapaxes(Jok, -1, -2))))
    np.testing.assert_allclose(got, np.broadcast_to(expected[:, None], ok.shape)[ok], rtol=0, atol=1e-9)
