"""Gepetto's parallel robots as people bring them (copies in ../shared/models/gepetto/): folders,
URDF limits without ranges, unassembled zero poses, every joint substitution of the format."""

from __future__ import annotations

import json
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from kinematics.cli.app import main
from kinematics.errors import (
    InvalidInputError,
    KinematicsWarning,
    MissingRangeError,
    ModelFileError,
    UnknownJointError,
    UnknownRobotError,
)
from kinematics.generic.assembly import OPEN_GAP, AssemblyError, assemble
from kinematics.generic.closedloop import ClosedLoop
from kinematics.model.robot import load_robot

from .conftest import GEPETTO

needs_models = pytest.mark.skipif(not GEPETTO.is_dir(), reason=f"Gepetto's models are not at {GEPETTO}")

MODELS = sorted(p.name for p in GEPETTO.iterdir() if p.is_dir() and list(p.glob("*.urdf"))) if GEPETTO.is_dir() else []
UNFIXABLE: set[str] = set()  # every folder loads (disney_robot with a warning: a misspelt substitution)
UNASSEMBLED = {"kangaroo_like", "kangaroo_like_2legs", "true_talos_2_legs"}
"""Models whose closed pose the assembly search does not find (see test_assembly_failures_say_so)."""


def _no_range_sides(urdf: Path) -> dict[str, tuple[bool, bool]]:
    """Independently of the loader: revolute/prismatic joints whose <limit> lacks lower/upper."""
    out = {}
    for j in ET.parse(urdf).getroot().iter("joint"):
        lim = j.find("limit")
        if j.get("type") in ("revolute", "prismatic"):
            out[j.get("name")] = (lim is None or "lower" not in lim.attrib, lim is None or "upper" not in lim.attrib)
    return out


def _closure_gap(robot, q) -> float:
    """Largest closure error at q from frame placements alone (not through the solver's
    constraint models): positions for a 3D pair, position and rotation (log3) for a 6D one."""
    model, data = robot.model, robot.model.createData()
    pin.framesForwardKinematics(model, data, q)
    worst = 0.0
    for c in robot.loops.closures:
        a = data.oMf[robot.frame_id(c.frame1)]
        b = data.oMf[robot.frame_id(c.frame2)]
        worst = max(worst, float(np.linalg.norm(a.translation - b.translation)))
        if c.type == "6d":
            worst = max(worst, float(np.linalg.norm(pin.log3(a.rotation.T @ b.rotation))))
    return worst


@needs_models
@pytest.mark.parametrize("name", [m for m in MODELS if m not in UNFIXABLE])
def test_every_model_folder_loads_and_ranges_are_never_zero(name):
    folder = GEPETTO / name
    robot = load_robot(folder)
    assert robot.name == name  # the folder names the robot (every Gepetto file is robot.urdf)
    sides = _no_range_sides(robot.urdf_path)
    for d in robot.dofs:
        if d.name in sides:  # a joint of the file itself (substituted ones are checked below)
            no_lo, no_hi = sides[d.name]
            assert (d.lower == -np.inf) == no_lo and (d.upper == np.inf) == no_hi, d
            assert d.range_given == (not no_lo and not no_hi)
        assert not (d.lower == 0.0 and d.upper == 0.0), f"{d.name} read as [0, 0]"


@needs_models
def test_universal_joint_zy_of_battobot():
    robot = load_robot(GEPETTO / "battobot_6d")
    names = robot.joint_names
    i = names.index("left_spherical_ankle_1_Z")
    assert names[i + 1] == "left_spherical_ankle_1_Y"  # Z first, then Y, at one origin
    m = robot.model
    jz, jy = m.getJointId("left_spherical_ankle_1_Z"), m.getJointId("left_spherical_ankle_1_Y")
    assert m.parents[jy] == jz
    assert np.allclose(m.jointPlacements[jy].homogeneous, np.eye(4), atol=0)
    data = m.createData()
    q = pin.neutral(m)
    pin.computeJointJacobians(m, data, q)
    axis_z = pin.getJointJacobian(m, data, jz, pin.LOCAL)[3:, m.joints[jz].idx_v]
    axis_y = pin.getJointJacobian(m, data, jy, pin.LOCAL)[3:, m.joints[jy].idx_v]
    np.testing.assert_allclose(axis_z, [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(axis_y, [0, 1, 0], atol=1e-15)
    assert "left_spherical_ankle_1_Z" in robot.unranged  # a substituted joint is passive, unbounded


@needs_models
def test_a_substitution_of_a_misspelt_joint_is_left_out_with_the_closest_names():
    # disney_robot's robot.yaml substitutes 'left_spherical_free_foot', which its URDF spells
    # 'left_sĥerical_free_foot': Gepetto's loader skips that substitution, and so does this one, loudly
    with pytest.warns(KinematicsWarning, match="did you mean 'left_sĥerical_free_foot'") as record:
        robot = load_robot(GEPETTO / "disney_robot")
    assert len([w for w in record if issubclass(w.category, KinematicsWarning)]) == 1
    kinds = {d.name: d.kind for d in robot.dofs}
    assert kinds["left_sĥerical_free_foot"] == "revolute"  # kept as the URDF has it
    assert "spherical_free_foot" not in kinds  # the right leg's twin was substituted
    assert {"spherical_free_foot_X", "spherical_free_foot_Y", "spherical_free_foot_Z"} <= set(kinds)


def test_model_folders(tmp_path):
    src = Path(__file__).parent / "models" / "fivebar_gepetto"
    one = tmp_path / "one"
    shutil.copytree(src, one)
    (one / "robot.urdf").rename(one / "five.urdf")
    assert load_robot(one).urdf_path.name == "five.urdf"  # the only URDF of a folder
    shutil.copy(one / "five.urdf", one / "other.urdf")
    with pytest.raises(ModelFileError, match="2 URDF files and no robot.urdf; name one of: five.urdf, other.urdf"):
        load_robot(one)
    (tmp_path / "empty").mkdir()
    with pytest.raises(ModelFileError, match="a folder with no .urdf file"):
        load_robot(tmp_path / "empty")
    with pytest.raises(UnknownRobotError, match="unknown robot ''"):
        load_robot("")  # not the current folder


def test_ranges_from_the_caller_and_the_sidecar(tmp_path):
    models = Path(__file__).parent / "models"
    robot = load_robot(models / "fivebar_gepetto", ranges={"mot1": (-1.0, 2.0)})
    d = robot.dofs[robot.joint_names.index("mot1")]
    assert (d.lower, d.upper) == (-1.0, 2.0)
    with pytest.raises(UnknownJointError, match="did you mean 'mot1'"):
        load_robot(models / "fivebar_gepetto", ranges={"mot_1": (-1.0, 1.0)})
    for bad in [(1.0, -1.0), (0.0, np.inf), (np.nan, 1.0)]:
        with pytest.raises(InvalidInputError):
            load_robot(models / "fivebar_gepetto", ranges={"mot1": bad})
    for f in ("fourbar.urdf", "fourbar.loops.yaml"):
        shutil.copy(models / f, tmp_path / f)
    side = tmp_path / "fourbar.loops.yaml"
    first = load_robot(tmp_path / "fourbar.urdf").joint_names[0]
    side.write_text(side.read_text() + f"ranges: {{{first}: [-0.5, 0.25]}}\n")
    d = load_robot(tmp_path / "fourbar.urdf").dofs[0]
    assert (d.lower, d.upper) == (-0.5, 0.25)


@needs_models
@pytest.mark.parametrize("name", [m for m in MODELS if m not in UNFIXABLE | UNASSEMBLED
                                  and (GEPETTO / m / "robot.yaml").exists()])
def test_assembly_closes_every_open_model(name):
    robot = load_robot(GEPETTO / name)
    q0 = robot.configuration(np.zeros(robot.nv))
    a = assemble(robot)
    # every one of these is exported open at q = 0 (the gap measured independently of the solver)
    assert _closure_gap(robot, q0) > 1e-3 and a.found and a.start_gap > 1e-3
    # closure tolerance 1e-10 (assembly.TOLERANCE) on the solver's errors; measured through frame
    # placements, rotations add the log3's rounding (~1e-15 per unit), so 1e-9 leaves margin
    assert _closure_gap(robot, a.q) <= 1e-9
    assert np.all(robot.within_limits(a.values, 1e-9))
    if a.found:
        assert "a closed pose found from the neutral pose" in a.description
        assert f"{a.start_gap:.3g}" in a.description


def test_a_closed_reference_is_kept():
    robot = load_robot("p2us")
    a = assemble(robot)
    assert not a.found and a.start_gap <= OPEN_GAP and a.stage == 1
    assert a.description == "the sidecar's reference configuration"
    assert a.moved <= 1e-6  # Newton only polishes a reference closed to ~1e-9 m


@needs_models
def test_assembly_holds_the_given_actuators():
    robot = load_robot(GEPETTO / "robot_delta")
    start = np.zeros(robot.nv)
    for name, value in zip(robot.loops.actuated, (0.2, -0.1), strict=True):
        start[robot.joint_names.index(name)] = value
    a = assemble(robot, start, hold=robot.loops.actuated)
    for name, value in zip(robot.loops.actuated, (0.2, -0.1), strict=True):
        assert a.values[robot.joint_names.index(name)] == pytest.approx(value, abs=1e-15)
    assert _closure_gap(robot, a.q) <= 1e-9
    assert "robot_delta" not in a.description and "given joint values" in a.description


@needs_models
@pytest.mark.parametrize("name", sorted(UNASSEMBLED))
def test_assembly_failures_say_so(name):
    with pytest.raises(AssemblyError, match=f"assembling {name} from the neutral pose"):
        assemble(load_robot(GEPETTO / name))


@needs_models
def test_cli_ranges_and_poses(capsys):
    fb = str(GEPETTO / "5bar_linkage")
    assert main(["info", fb, "--json"]) == 0
    joints = json.loads(capsys.readouterr().out)["joints"]
    mot1 = next(j for j in joints if j["name"] == "mot1")
    assert mot1["lower"] is None and mot1["upper"] is None and mot1["range_given"] is False
    assert main(["info", fb]) == 0
    assert "none given" in capsys.readouterr().out
    # a workspace needs the actuators' ranges: said at once, naming them and the option
    assert main(["workspace-volume", fb]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "mot1, mot2" in err and "--range mot1=LO:HI" in err
    with pytest.raises(MissingRangeError) as info:
        from kinematics.mechanisms import mechanism_of

        mechanism_of(load_robot(fb)).require("margin", "a workspace")
    assert info.value.joints == ("mot1", "mot2")
    assert main(["info", fb, "--range", "mot1=1:0"]) == 2
    assert "finite LO < HI" in capsys.readouterr().err
    # mobility without --q analyses a closed pose and says which
    assert main(["mobility", fb]) == 0
    assert "a closed pose found from the neutral pose (q = 0) (closure gap 1.57" in capsys.readouterr().out


def _closed_pose_in_plane(robot):
    """(data, origin) at the default closed pose: Pinocchio data with frames placed, and a
    function joint name -> its origin's in-plane (y, z) coordinates (both five-bars here move in
    the y-z plane)."""
    q = ClosedLoop(robot).reference
    d = robot.model.createData()
    pin.framesForwardKinematics(robot.model, d, q)

    def origin(name):
        return d.oMi[robot.model.getJointId(name)].translation[1:]

    return q, d, origin


def _grid_centres(lo: np.ndarray, hi: np.ndarray, n: int) -> tuple[np.ndarray, float]:
    """The centres (n * n, 2) of an n x n grid over the box [lo, hi] and one cell's area."""
    h = (hi - lo) / n
    g = np.meshgrid(*(lo[i] + h[i] * (np.arange(n) + 0.5) for i in range(2)), indexing="ij")
    return np.stack(g, axis=-1).reshape(-1, 2), float(h[0] * h[1])


def _robot_delta_reference(robot, n: int) -> dict[str, float]:
    """robot_delta's workspace area [m^2] per elbow of chain 1 and their union, by counting the
    centres of an n x n grid, from its geometry alone (not the batched solver): the end effector E
    is a five-bar's tip (chain 1: A1 -> B1 -> E, chain 2: A2 -> B2 -> E, lengths read at a closed
    pose); two parallelograms hold its orientation, so free2_rod1 (connecting rod 1 -> effector)
    turns by minus the rod's turn, and its range [-pi/2, pi/2] is the one joint limit that binds."""
    from .fivebar import perp

    q, d, origin = _closed_pose_in_plane(robot)
    m = robot.model
    A1, B1, E, A2, B2 = (origin(n_) for n_ in ("mot1_rod1", "free1_rod1", "free2_rod1", "mot1_rod2", "free1_rod2"))
    a1, b1, a2, b2 = (float(np.linalg.norm(v)) for v in (B1 - A1, E - B1, B2 - A2, E - B2))
    j = m.getJointId("free2_rod1")
    s = np.sign(d.oMi[j].rotation[0, 2])  # its axis (local z) along +-x, the plane's normal
    k = robot.joint_names.index("free2_rod1")
    q_ref, phi_ref = robot.values_from_configuration(q)[k], np.arctan2(*(E - B1)[::-1])
    lo, hi = robot.dofs[k].lower, robot.dofs[k].upper
    P, cell = _grid_centres(np.minimum(A1, A2) - (a1 + b1), np.maximum(A1, A2) + (a1 + b1), n)
    r2 = np.linalg.norm(P - A2, axis=1)
    chain2 = (r2 >= abs(a2 - b2)) & (r2 <= a2 + b2)
    D = P - A1
    r = np.linalg.norm(D, axis=1)
    x = (a1**2 - b1**2 + r**2) / (2 * r)
    h2 = a1**2 - x**2
    out = {}
    for side in (1, -1):  # elbow B1 left / right of A1 -> E (tests/fivebar.py's circles, vectorised)
        B = A1 + (x / r)[:, None] * D + side * (np.sqrt(np.maximum(h2, 0)) / r)[:, None] * perp(D.T).T
        phi = np.arctan2((P - B)[:, 1], (P - B)[:, 0])
        val = (q_ref - s * (phi - phi_ref) + np.pi) % (2 * np.pi) - np.pi
        out[side] = chain2 & (h2 >= 0) & (val >= lo) & (val <= hi)
    return {"+1": out[1].sum() * cell, "-1": out[-1].sum() * cell, "union": (out[1] | out[-1]).sum() * cell}


@needs_models
def test_robot_delta_workspace_holds_its_geometric_reference(capsys):
    """robot_delta's equations do not split in the block solver's dependency order as first found
    (an ancestor of the end effector that moves nothing the task measures), and it was read as
    not translational from a pose closed to 1e-12 only: its workspace must come out of the generic
    path and hold an independent reference within the estimate."""
    path = GEPETTO / "robot_delta"
    pi = "3.141592653589793"
    ranges = ["--range", f"mot1_rod1=-{pi}:{pi}", "--range", f"mot1_rod2=-{pi}:{pi}"]
    assert main(["workspace-volume", str(path), *ranges, "--rtol", "1e-1", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    robot = load_robot(path, ranges={"mot1_rod1": (-np.pi, np.pi), "mot1_rod2": (-np.pi, np.pi)})
    fine, coarse = _robot_delta_reference(robot, 2400), _robot_delta_reference(robot, 1200)
    # the grid count's own error: bounded by its change from the coarse grid (first order at
    # worst in h, so the finer one is at least twice as close)
    ref_err = {k: abs(fine[k] - coarse[k]) for k in fine}
    assert abs(data["area_m2"] - fine["union"]) <= data["error_estimate"] + ref_err["union"]
    modes = data["modes"]
    assert len(modes) == 2
    got = sorted((v["area"], v["error_estimate"]) for v in modes.values())
    want = sorted([(fine["+1"], ref_err["+1"]), (fine["-1"], ref_err["-1"])])
    for (area, est), (ref, err) in zip(got, want, strict=True):
        assert abs(area - ref) <= est + err, (area, ref, est, err)


def test_equations_that_do_not_split_fall_back_to_the_whole_system(monkeypatch):
    """Where the block decomposition cannot be built, the batched solver solves every unknown at
    once instead of refusing the robot; it still finds the five-bar fixture's tip inside reach."""
    from kinematics.errors import UnsupportedRobotError
    from kinematics.generic.loop_batch import LoopBatch

    from .fivebar import FiveBar

    def refuse(self):
        raise UnsupportedRobotError("x", "block 0 of the loop equations uses a joint that no earlier block determines")

    monkeypatch.setattr(LoopBatch, "block_models", property(refuse))
    robot = load_robot(Path(__file__).parent / "models" / "fivebar_gepetto" / "robot.urdf")
    batch = LoopBatch.from_robot(robot)
    assert batch.solver == "whole"
    five = FiveBar.from_robot(robot)
    P = np.array([[0.05, 0.35], [0.9, 0.9]])
    inside = np.all(five.reach(P) > 1e-3, axis=1)  # clear of the reach circles by 1 mm
    assert inside.tolist() == [True, False]
    assert batch.ik(P).found.any(axis=1).tolist() == inside.tolist()


def _fivebar_effector_reference(robot, n: int) -> float:
    """5bar_linkage's workspace area [m^2] by counting the centres of an n x n grid, from its
    geometry alone: its end effector sits on chain 2's distal link, off the tip P. For a point E,
    the elbow B2 is on circle(A2, a2) at distance e from E (two choices); the link's fixed angle
    then places P, which chain 1 must reach (|P - A1| within its annulus). The actuators' ranges are
    full turns and the passive joints have none, so reach is the only limit."""
    _, d, origin = _closed_pose_in_plane(robot)
    A1, B1, A2, B2 = (origin(n_) for n_ in ("mot1", "free1", "mot2", "free2"))
    P0 = d.oMf[robot.frame_id("closedloop1_B")].translation[1:]
    E0 = d.oMf[robot.frame_id("effector")].translation[1:]
    a1, b1 = np.linalg.norm(B1 - A1), np.linalg.norm(P0 - B1)
    a2, b2, e = np.linalg.norm(B2 - A2), np.linalg.norm(P0 - B2), np.linalg.norm(E0 - B2)

    def angle(v):
        return np.arctan2(v[..., 1], v[..., 0])

    delta = angle(P0 - B2) - angle(E0 - B2)
    E, cell = _grid_centres(np.minimum(A1, A2) - (a2 + e), np.maximum(A1, A2) + (a2 + e), n)
    D = E - A2
    r = np.linalg.norm(D, axis=1)
    x = (a2**2 - e**2 + r**2) / (2 * r)
    h2 = a2**2 - x**2
    perp = np.stack([-D[:, 1], D[:, 0]], axis=1)
    inside = np.zeros(len(E), dtype=bool)
    for side in (1, -1):
        B = A2 + (x / r)[:, None] * D + side * (np.sqrt(np.maximum(h2, 0)) / r)[:, None] * perp
        phi = angle(E - B) + delta
        P = B + b2 * np.stack([np.cos(phi), np.sin(phi)], axis=1)
        d1 = np.linalg.norm(P - A1, axis=1)
        inside |= (h2 >= 0) & (d1 >= abs(a1 - b1)) & (d1 <= a1 + b1)
    return float(inside.sum() * cell)


@needs_models
def test_gepetto_fivebar_area_holds_its_geometric_reference(capsys):
    """5bar_linkage (exported open at q = 0, no ranges in its URDF) through the generic path: its
    area within the reported estimate of an independent grid count (2.44111 m^2)."""
    path = GEPETTO / "5bar_linkage"
    pi = "3.141592653589793"
    assert main(["workspace-volume", str(path), "--range", f"mot1=-{pi}:{pi}", "--range", f"mot2=-{pi}:{pi}",
                 "--rtol", "1e-1", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    robot = load_robot(path)
    fine, coarse = _fivebar_effector_reference(robot, 2400), _fivebar_effector_reference(robot, 1200)
    assert abs(data["area_m2"] - fine) <= data["error_estimate"] + abs(fine - coarse)


def test_a_serial_arm_without_ranges_asks_for_them(tmp_path, capsys):
    """A serial arm whose revolute has a <limit> without lower/upper: no [0, 0] joint, and its
    workspace names the joint that needs a range; --range gives it (the continuous joint needs none)."""
    src = (Path(__file__).parent / "models" / "arm3r_wedge.urdf").read_text()
    text = src.replace('<limit lower="0.5" upper="2.0" effort="10" velocity="1"/>', '<limit effort="10" velocity="1"/>')
    assert text != src
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(text)
    robot = load_robot(urdf)
    assert robot.unranged == ("elbow",)
    assert main(["workspace-volume", str(urdf)]) == 2
    err = capsys.readouterr().err
    assert "needs the range of elbow," in err and "--range elbow=LO:HI" in err and "pitch" not in err
    # --range gives it: the joint table is then the file's own (every command loads robots the same way;
    # a volume of this spatial arm would cost minutes, the table is what the volume reads)
    with_range = main(["info", str(urdf), "--range", "elbow=0.5:2.0", "--json"])
    original = main(["info", str(Path(__file__).parent / "models" / "arm3r_wedge.urdf"), "--json"])
    assert with_range == original == 0
    out = capsys.readouterr().out
    first, second = (json.loads(part) for part in out.replace("}\n{", "}\n\x00{").split("\x00"))
    assert first["joints"] == second["joints"]
    assert next(j for j in first["joints"] if j["name"] == "elbow")["lower"] == 0.5
