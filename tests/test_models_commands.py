"""`info`, `fk`, `jacobian`, `mobility` and `workspace-volume` on every Gepetto model folder, as a
new user runs them (no --q: a closed loop at its default closed pose), through `main`.

The answers are checked against Pinocchio directly: the reported end-effector placement is
recomputed with `framesForwardKinematics` at the reported joint values, the loops are checked
closed there from the closure frames' placements (pairs read from robot.yaml, not through the
loader's loop description), the numeric mobility from a loop Jacobian built of frame Jacobians
(not the solver's constraint models), the constrained Jacobian against finite differences of
closed poses.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from kinematics.cli.app import main
from kinematics.errors import KinematicsError, KinematicsWarning
from kinematics.generic.assembly import AssemblyError
from kinematics.generic.closedloop import ClosedLoop
from kinematics.model.robot import load_robot

from .conftest import GEPETTO

needs_models = pytest.mark.skipif(not GEPETTO.is_dir(), reason=f"Gepetto's models are not at {GEPETTO}")
MODELS = (sorted(str(p.relative_to(GEPETTO)) for p in GEPETTO.rglob("*") if p.is_dir() and any(p.glob("*.urdf")))
          if GEPETTO.is_dir() else [])
MISSPELT = {"disney_robot"}  # its robot.yaml substitutes a joint its URDF misspells (upstream defect): loads, warns
UNASSEMBLED = {"kangaroo_like", "kangaroo_like_2legs", "true_talos_2_legs"}  # the assembly search fails (known)
OPEN_TREE = {"kangaroo_like_2leg"}  # no robot.yaml: loaded as an open tree, fk needs every joint value

CLOSURE_TOL = 1e-9
"""Closure residual at a reported pose [m, rad]: the solver closes to 1e-12 (the assembly to
1e-10, then Newton polishes); measured through frame placements, a rotation's log3 adds ~1e-15 per
unit of rounding, so 1e-9 leaves a margin of 1e3 on the looser of the two."""

POSITION_TOL = 1e-12
"""Reported vs recomputed end-effector position [m]: the same float64 kinematics at the same
configuration (JSON keeps floats exactly), so only the order of operations differs: chains of up to
~20 joints of <= 1 m at ~1e-16 relative rounding each give ~1e-14 m; 1e-12 leaves two decades."""


def run(capsys, *argv: str) -> tuple[int, dict, str]:
    code = main([*argv, "--json"])
    out, err = capsys.readouterr()
    return code, (json.loads(out) if code == 0 else {}), err


def closures(folder: Path) -> list[tuple[str, str, str]]:
    """(frame A, frame B, '3d' or '6d') from robot.yaml itself (6D where `type` is absent)."""
    spec = yaml.safe_load((folder / "robot.yaml").read_text())
    pairs = spec["closed_loop"]
    kinds = [t.lower() for t in spec.get("type", ["6d"] * len(pairs))]
    return [(a, b, k) for (a, b), k in zip(pairs, kinds, strict=True)]


def configuration(model: pin.Model, values: dict[str, float]) -> np.ndarray:
    """A Pinocchio configuration from joint values by name (1-DOF joints: one entry of q each)."""
    q = pin.neutral(model)
    for name, v in values.items():
        j = model.joints[model.getJointId(name)]
        assert j.nq == 1, name
        q[j.idx_q] = v
    return q


def placement(model: pin.Model, data: pin.Data, name: str) -> pin.SE3:
    ids = [i for i, f in enumerate(model.frames) if f.name == name]
    body = [i for i in ids if model.frames[i].type == pin.FrameType.BODY]
    return data.oMf[(body or ids)[0]]


def closure_gap(model: pin.Model, q: np.ndarray, pairs: list[tuple[str, str, str]]) -> float:
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    worst = 0.0
    for a, b, kind in pairs:
        A, B = placement(model, data, a), placement(model, data, b)
        worst = max(worst, float(np.linalg.norm(A.translation - B.translation)))
        if kind == "6d":
            worst = max(worst, float(np.linalg.norm(pin.log3(A.rotation.T @ B.rotation))))
    return worst


def loop_jacobian(model: pin.Model, q: np.ndarray, pairs: list[tuple[str, str, str]]) -> np.ndarray:
    """Rows: relative velocity of each pair's frames (both origins coincide at a closed pose), world
    axes; a 6D pair adds the relative angular velocity."""
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    rows = []
    for a, b, kind in pairs:
        ja, jb = (pin.getFrameJacobian(model, data, model.getFrameId(n), pin.LOCAL_WORLD_ALIGNED) for n in (a, b))
        rows.append((ja - jb)[: 6 if kind == "6d" else 3])
    return np.vstack(rows)


@needs_models
def test_every_folder_is_covered():
    assert len(MODELS) == 19 and "old/digit_like_2legs" in MODELS
    assert set(MODELS) >= MISSPELT | UNASSEMBLED | OPEN_TREE


@needs_models
@pytest.mark.parametrize("name", MODELS)
def test_info_fk_mobility_on_every_model(name, capsys):
    folder = GEPETTO / name
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always", KinematicsWarning)
        robot = load_robot(folder)
    assert bool(record) == (name in MISSPELT)  # a substitution of a misspelt joint is left out, loudly
    code, data, err = run(capsys, "info", str(folder))
    assert code == 0, err
    if name in MISSPELT:
        assert err.startswith("kinematics info: warning: ") and "did you mean" in err and len(err.splitlines()) == 1
    if name in OPEN_TREE:
        assert robot.loops is None and data["mobility"] == robot.nv and data["grubler_mobility"] is None
        code, _, err = run(capsys, "fk", str(folder))
        assert code == 2 and "needs joint values, one per degree of freedom (130)" in err
        code, fk, err = run(capsys, "fk", str(folder), "--q", *["0"] * robot.nv)
        assert code == 0, err
        data_ = robot.model.createData()
        pin.framesForwardKinematics(robot.model, data_, pin.neutral(robot.model))
        want = placement(robot.model, data_, robot.tool_frame).translation
        assert np.max(np.abs(np.array(fk["position"]) - want)) <= POSITION_TOL
        code, mob, err = run(capsys, "mobility", str(folder))
        assert code == 0 and mob["numeric"]["mobility"] == robot.nv, err
        return
    pairs = closures(folder)
    if name in UNASSEMBLED:
        with pytest.raises(AssemblyError) as info:
            _ = ClosedLoop(robot).assembly
        assert data["mobility"] is None and data["mobility_pose"] is None
        assert isinstance(data["grubler_mobility"], int) and "no closed pose found" in data["mobility_note"]
        for command in ("fk", "mobility"):
            code, _, err = run(capsys, command, str(folder))
            assert code == 2 and err == f"kinematics {command}: error: {info.value}\n"
        return

    # fk without --q: the end effector at a closed pose, which the report names
    code, fk, err = run(capsys, "fk", str(folder))
    assert code == 0, err
    assert fk["frame"] == robot.tool_frame and "closed pose found from the neutral pose" in fk["configuration"]
    q = configuration(robot.model, fk["joint_values"])
    assert closure_gap(robot.model, q, pairs) <= CLOSURE_TOL
    d = robot.model.createData()
    pin.framesForwardKinematics(robot.model, d, q)
    M = placement(robot.model, d, fk["frame"])
    assert np.max(np.abs(np.array(fk["position"]) - M.translation)) <= POSITION_TOL
    assert np.max(np.abs(np.array(fk["rotation"]) - M.rotation)) <= POSITION_TOL
    motors = yaml.safe_load((folder / "robot.yaml").read_text())["name_mot"]
    assert fk["actuated"] == motors and fk["q"] == [fk["joint_values"][m] for m in motors]

    # the numeric mobility (info and mobility) is nv - rank of the loop Jacobian at that pose;
    # the rank is unambiguous: no singular value between 1e-12 and 1e-6 of the largest
    s = np.linalg.svd(loop_jacobian(robot.model, q, pairs), compute_uv=False)
    assert not np.any((s > 1e-12 * s[0]) & (s < 1e-6 * s[0])), s
    mobility = robot.nv - int(np.sum(s >= 1e-6 * s[0]))
    assert data["mobility"] == mobility and "closed pose found" in data["mobility_pose"]
    code, mob, err = run(capsys, "mobility", str(folder))
    assert code == 0 and mob["numeric"]["mobility"] == mobility, err


def _position(robot, q: np.ndarray, frame: str) -> np.ndarray:
    d = robot.model.createData()
    pin.framesForwardKinematics(robot.model, d, q)
    return placement(robot.model, d, frame).translation.copy()


def finite_difference(loop: ClosedLoop, q: np.ndarray, frame: str, h: float) -> np.ndarray:
    """3 x n_actuated: the frame origin's motion per actuator rate, by central differences of
    closed poses (the actuators moved by +-h, the loops closed by Newton from q)."""
    robot = loop.robot
    a0 = robot.values_from_configuration(q)[loop.actuated_dofs]
    cols = []
    for k in range(len(a0)):
        ends = []
        for sign in (1, -1):
            a = a0.copy()
            a[k] += sign * h
            ends.append(_position(robot, loop.solve(a, q0=q).q, frame))
        cols.append((ends[0] - ends[1]) / (2 * h))
    return np.array(cols).T


@needs_models
def test_jacobian_of_a_leg(capsys):
    """talos_like: the default end effector (closure frame on the ankle rod) is refused, naming held
    frames; the foot's Jacobian matches finite differences of closed poses."""
    folder = str(GEPETTO / "talos_like")
    code, _, err = run(capsys, "jacobian", folder)
    assert code == 2 and err.count("\n") == 1 and "type II" in err and "foot_part" in err
    assert "closed pose found from the neutral pose" in err  # which pose
    code, jac, err = run(capsys, "jacobian", folder, "--frame", "foot")
    assert code == 0, err
    G = np.array(jac["jacobian"])
    assert G.shape == (6, 6) and jac["rows"] == ["x", "y", "z", "wx", "wy", "wz"]
    robot = load_robot(folder)
    loop = ClosedLoop(robot)
    q = configuration(robot.model, jac["joint_values"])
    assert closure_gap(robot.model, q, closures(GEPETTO / "talos_like")) <= CLOSURE_TOL
    # h = 1e-4 rad: truncation ~h^2 |x'''| ~ 1e-8 m/rad for a leg of ~1 m, closure noise 1e-12 m / h
    # = 1e-8 m/rad; 1e-6 leaves two decades over both
    fd = finite_difference(loop, q, "foot", 1e-4)
    np.testing.assert_allclose(G[:3], fd, atol=1e-6)
    code, tr, _ = run(capsys, "jacobian", folder, "--frame", "foot", "--task", "translation")
    assert code == 0 and np.array_equal(np.array(tr["jacobian"]), G[:3])


@needs_models
def test_a_frame_on_a_spinning_rod(capsys):
    """digit_like's end effector closedloop1_B: with the actuators held its orientation is free and its
    position is not (shown by closing the loops again from a disturbed pose), so the 6-row Jacobian
    is refused and the translation rows are answered."""
    folder = GEPETTO / "digit_like"
    robot = load_robot(folder)
    loop = ClosedLoop(robot)
    q0 = loop.newton(loop.reference)[0]
    rng = np.random.default_rng(3)
    v = np.zeros(robot.nv)
    v[loop.passive_v] = rng.uniform(-0.05, 0.05, len(loop.passive_v))
    q1, err, _ = loop.newton(pin.integrate(robot.model, q0, v), max_iter=100)  # passive joints only
    assert err <= 1e-12
    pairs = closures(folder)
    assert closure_gap(robot.model, q1, pairs) <= CLOSURE_TOL
    d0, d1 = robot.model.createData(), robot.model.createData()
    pin.framesForwardKinematics(robot.model, d0, q0)
    pin.framesForwardKinematics(robot.model, d1, q1)
    A0, A1 = placement(robot.model, d0, "closedloop1_B"), placement(robot.model, d1, "closedloop1_B")
    assert np.linalg.norm(A0.translation - A1.translation) <= CLOSURE_TOL  # position held
    assert np.linalg.norm(pin.log3(A0.rotation.T @ A1.rotation)) > 1e-3  # orientation not
    code, _, err = run(capsys, "jacobian", str(folder))
    assert code == 2 and "its orientation can move with the actuators locked" in err and "--task translation" in err
    code, tr, err = run(capsys, "jacobian", str(folder), "--task", "translation")
    assert code == 0 and np.array(tr["jacobian"]).shape == (3, 6), err
    # mobility says the same instead of "a singular configuration"
    code, mob, _ = run(capsys, "mobility", str(folder))
    assert code == 0 and any("about its own origin (its position is held)" in n for n in mob["notes"])


@needs_models
@pytest.mark.parametrize("name", ["digit_like", "true_talos_2_legs"])
def test_workspace_of_a_redundant_leg_says_why_not(name, capsys):
    folder = GEPETTO / name
    robot = load_robot(folder)
    ranges = [a for m in robot.loops.actuated for a in ("--range", f"{m}={-math.pi}:{math.pi}")]
    for extra in ([], ranges):  # said before the missing ranges, and with them
        code = main(["workspace-volume", str(folder), *extra])
        out, err = capsys.readouterr()
        n = len(robot.loops.actuated)
        assert code == 2 and out == "" and err.count("\n") == 1, err
        assert f"{n} actuators" in err and "redundant" in err and f"up to {n - 3} actuator freedom(s)" in err


def test_closed_loop_commands_on_the_fixture(capsys):
    """Without Gepetto's folder: the five-bar fixture's fk at its closed reference, --frame honoured,
    the constrained Jacobian the solver's own, flags of the closed-form families refused."""
    fb = Path(__file__).parent / "models" / "fivebar_gepetto"
    robot = load_robot(fb)
    loop = ClosedLoop(robot)
    code, fk, err = run(capsys, "fk", str(fb), "--frame", "closedloop3D_B")
    assert code == 0 and fk["frame"] == "closedloop3D_B", err
    q = configuration(robot.model, fk["joint_values"])
    assert np.max(np.abs(np.array(fk["position"]) - _position(robot, q, "closedloop3D_B"))) <= POSITION_TOL
    code, jac, err = run(capsys, "jacobian", str(fb))
    assert code == 0, err
    q = configuration(robot.model, jac["joint_values"])
    np.testing.assert_array_equal(jac["jacobian"], loop.constrained_jacobian(q))  # the same computation
    for flag in (["--position", "0", "0", "0"], ["--mode", "+"]):
        code, _, err = run(capsys, "jacobian", str(fb), *flag)
        assert code == 2 and "no closed forms" in err
    code, _, err = run(capsys, "fk", "p2us", "--frame", "base")
    assert code == 2 and "--frame" in err
    with pytest.raises(KinematicsError):
        robot.frame_id("no_such_frame")
    code, _, err = run(capsys, "fk", str(fb), "--frame", "no_such_frame")
    assert code == 2 and "unknown frame" in err
