"""Compiled batched kinematics held to Pinocchio, to finite differences of itself, and its CLI."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from kinematics.cli.app import main
from kinematics.errors import InvalidInputError, UnknownFrameError, UnsupportedRobotError
from kinematics.generic.batched import BLOCK, BatchedKinematics, batched_fk, batched_jacobian, configurations
from kinematics.model.robot import load_robot

MODELS = Path(__file__).parent / "models"
ONE_DOF = str(MODELS / "one_dof_batched.urdf")
PRISMATIC = str(MODELS / "prismatic_chain_batched.urdf")
ROBOTS = ["ur5", "panda", "kinova", "scara", ONE_DOF, PRISMATIC]

# Both sides compose the same ~10 placements in double precision: each product of unit-norm
# rotations adds a few ulp (~1e-16), positions are within ~1 m, so agreement is ~1e-15; the
# issue's bound 1e-12 leaves three orders of margin and still catches any wrong axis or sign.
TOL = 1e-12


@pytest.fixture(scope="module", params=ROBOTS, ids=lambda s: Path(s).stem)
def robot(request):
    return load_robot(request.param)


def random_values(robot, n, rng):
    """n rows of joint values: angles over a full turn and more, slides within their limits."""
    out = np.empty((n, robot.nv))
    for i, d in enumerate(robot.dofs):
        if d.kind == "prismatic":
            out[:, i] = rng.uniform(d.lower, d.upper, n)
        else:
            out[:, i] = rng.uniform(-4.0, 4.0, n)
    return out


def test_every_frame_matches_pinocchio(robot, rng):
    v = random_values(robot, 24, rng)
    q = np.array([robot.configuration(row) for row in v])  # Robot's own per-row conversion
    frames = range(len(robot.model.frames))
    compiled = [BatchedKinematics.from_model(robot.model, f, robot.name) for f in frames]
    results = [c.fk_jacobian(q) for c in compiled]
    for c, (poses, _) in zip(compiled, results, strict=True):
        # The FK-only kernel (blocked for SIMD) and the Jacobian kernel: the same numbers.
        assert np.array_equal(c.fk(q).rows, poses.rows)
    model, data = robot.model, robot.model.createData()
    err = np.zeros(3)
    for n, qn in enumerate(q):
        pin.framesForwardKinematics(model, data, qn)
        pin.computeJointJacobians(model, data, qn)
        for f, (poses, J) in zip(frames, results, strict=True):
            M = data.oMf[f]
            # (Pinocchio hands a 1-DOF model's 6 x 1 Jacobian back as a vector.)
            Jref = pin.getFrameJacobian(model, data, f, pin.LOCAL_WORLD_ALIGNED).reshape(6, model.nv)
            err = np.maximum(err, [
                np.abs(poses.position[n] - M.translation).max(),
                np.abs(poses.rotation[n] - M.rotation).max(),
                np.abs(J[n] - Jref).max(),
            ])
    assert err.max() <= TOL, f"max |error| position, rotation, Jacobian: {err}"


def test_configurations_match_robot_configuration(robot, rng):
    v = random_values(robot, 5, rng)
    expected = np.array([robot.configuration(row) for row in v])
    assert np.array_equal(configurations(robot, v), expected)
    deg = np.degrees(v)
    for i, d in enumerate(robot.dofs):
        if d.kind == "prismatic":
            deg[:, i] = v[:, i]
    np.testing.assert_allclose(configurations(robot, deg, degrees=True), expected, rtol=0, atol=1e-15)


@pytest.mark.parametrize("name", ["ur5", "kinova", PRISMATIC], ids=lambda s: Path(s).stem)
def test_jacobian_matches_finite_differences_of_fk(name, rng):
    """Central differences of the compiled FK itself (an independent path to the Jacobian).

    Step h = 1e-6: truncation h^2/6 |p'''| <= ~1e-13 for ~1 m arms; rounding eps |p| / h ~ 1e-10.
    Angular rows from R(+h) R(-h)^T = exp(2h [w]x) (world axes): vee of its skew part / 2h, with
    the same orders of error. 1e-8 is two orders above both and far below any column error.
    """
    robot = load_robot(name)
    kin = BatchedKinematics.from_robot(robot)
    v = random_values(robot, 8, rng)
    J = kin.jacobian(configurations(robot, v))
    h = 1e-6
    for i in range(robot.nv):
        step = np.zeros(robot.nv)
        step[i] = h
        plus, minus = kin.fk(configurations(robot, v + step)), kin.fk(configurations(robot, v - step))
        lin = (plus.position - minus.position) / (2 * h)
        A = plus.rotation @ np.swapaxes(minus.rotation, 1, 2)
        ang = np.stack([A[:, 2, 1] - A[:, 1, 2], A[:, 0, 2] - A[:, 2, 0], A[:, 1, 0] - A[:, 0, 1]], -1) / (4 * h)
        np.testing.assert_allclose(J[:, :3, i], lin, rtol=0, atol=1e-8)
        np.testing.assert_allclose(J[:, 3:, i], ang, rtol=0, atol=1e-8)


def test_large_angles_match_pinocchio():
    """Angles far beyond a turn go through the kernel's own argument reduction (and, past 1e5 rad,
    libm's): both must agree with Pinocchio's sin/cos."""
    robot = load_robot(ONE_DOF)
    angles = np.concatenate([np.linspace(-1e6, 1e6, 4001), np.arange(-8, 9) * np.pi / 4,
                             [1e5, -1e5, np.nextafter(1e5, 2e5), 3e8]])[:, None]
    q = configurations(robot, angles)
    kin = BatchedKinematics.from_robot(robot)
    fid = robot.frame_id()
    for poses in (kin.fk(q), kin.fk_jacobian(q)[0]):  # the blocked FK kernel and the Jacobian kernel
        for n, qn in enumerate(q):
            pin.framesForwardKinematics(robot.model, robot.data, qn)
            M = robot.data.oMf[fid]
            assert np.abs(poses.rotation[n] - M.rotation).max() <= TOL
            assert np.abs(poses.position[n] - M.translation).max() <= TOL


def test_chunks_and_threads_do_not_change_results(ur5, rng):
    kin = BatchedKinematics.from_robot(ur5)
    q = configurations(ur5, random_values(ur5, 9 * BLOCK + 7, rng))
    many, J = kin.fk_jacobian(q)
    one, J1 = kin.fk_jacobian(q, threads=1)
    assert np.array_equal(many.rows, one.rows) and np.array_equal(J, J1)
    rows = np.concatenate([kin.fk(q[s : s + 100]).rows for s in range(0, len(q), 100)])
    assert np.array_equal(rows, many.rows)
    assert np.array_equal(kin.fk(q).rows, many.rows)  # the FK-only kernel: the same numbers


def test_single_configuration_and_convenience_functions(ur5, rng):
    q = ur5.configuration(random_values(ur5, 1, rng)[0])
    fid = ur5.frame_id("wrist_2_link")
    poses = batched_fk(ur5, q, "wrist_2_link")
    J = batched_jacobian(ur5, q[None], "wrist_2_link")
    data = ur5.model.createData()
    pin.framesForwardKinematics(ur5.model, data, q)
    M = data.oMf[fid]
    ref = pin.computeFrameJacobian(ur5.model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)
    assert poses.position.shape == (1, 3) and J.shape == (1, 6, 6)
    assert np.abs(poses.position[0] - M.translation).max() <= TOL
    assert np.abs(poses.rotation[0] - M.rotation).max() <= TOL
    assert np.abs(J[0] - ref).max() <= TOL
    assert np.all(J[0][:, 5] == 0.0) and np.linalg.norm(J[0][:, 4]) > 0.5  # wrist 3 does not move it


def test_bad_input_is_refused(ur5, rng):
    kin = BatchedKinematics.from_robot(ur5)
    with pytest.raises(InvalidInputError, match=r"shape \(N, 6\)"):
        kin.fk(np.zeros((3, 5)))
    q = np.zeros((3, 6))
    q[1, 2] = np.nan
    with pytest.raises(InvalidInputError, match="row 1"):
        kin.fk(q)
    with pytest.raises(InvalidInputError, match="threads"):
        kin.fk(np.zeros((3, 6)), threads=0)
    with pytest.raises(InvalidInputError, match=r"shape \(3, 12\)"):
        kin.fk(np.zeros((3, 6)), out=np.empty((3, 11)))
    with pytest.raises(UnknownFrameError):
        BatchedKinematics.from_robot(ur5, "no_such_frame")
    kinova = load_robot("kinova")
    q = configurations(kinova, np.zeros((2, 6)))
    q[1, 0] = 2.0  # (cos, sin) = (2, 0) is no rotation
    with pytest.raises(InvalidInputError, match="unit norm"):
        batched_fk(kinova, q)
    with pytest.raises(InvalidInputError, match="rows of 6"):
        configurations(kinova, np.zeros((2, 9)))


def test_unsupported_joints_are_named():
    model = pin.buildModelFromUrdf(ONE_DOF, pin.JointModelFreeFlyer())
    with pytest.raises(UnsupportedRobotError, match="FreeFlyer.*revolute.*continuous.*prismatic.*fixed"):
        BatchedKinematics.from_model(model, model.nframes - 1, "floating")
    model = pin.Model()
    model.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), "ball")
    with pytest.raises(UnsupportedRobotError, match="'ball' is a Spherical joint"):
        BatchedKinematics.from_model(model, 0)


# -- CLI ------------------------------------------------------------------------------------------
def fk_json(capsys, robot, q, *extra):
    import json

    assert main(["fk", robot, "--q", *(repr(float(x)) for x in q), *extra, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("suffix", [".csv", ".npy"])
def test_cli_q_file_rows_match_single_fk(tmp_path, capsys, rng, suffix):
    """Kinova (continuous joints): --q-file rows are angles, one per degree of freedom."""
    robot = load_robot("kinova")
    v = random_values(robot, 4, rng)
    qfile, out = tmp_path / f"q{suffix}", tmp_path / f"p{suffix}"
    if suffix == ".npy":
        np.save(qfile, v)
    else:
        np.savetxt(qfile, v, delimiter=",", fmt="%.17g", header=",".join(robot.joint_names), comments="")
    assert main(["fk", "kinova", "--q-file", str(qfile), "--out", str(out)]) == 0
    assert "4 configurations" in capsys.readouterr().out
    table = np.load(out) if suffix == ".npy" else np.loadtxt(out, delimiter=",", skiprows=1)
    assert table.shape == (4, 12)
    for row, values in zip(table, v, strict=True):
        ref = fk_json(capsys, "kinova", values)
        assert np.abs(row[:3] - ref["position"]).max() <= TOL
        assert np.abs(row[3:] - np.ravel(ref["rotation"])).max() <= TOL
    if suffix == ".csv":
        assert out.read_text().splitlines()[0] == "x,y,z,r00,r01,r02,r10,r11,r12,r20,r21,r22"


def test_cli_planar_arm_degrees_and_frame(tmp_path, capsys):
    qfile, out = tmp_path / "q.csv", tmp_path / "p.csv"
    qfile.write_text("90,0\n0,90\n")
    assert main(["fk", "scara", "--q-file", str(qfile), "--out", str(out), "--degrees", "--frame", "tool"]) == 0
    np.testing.assert_allclose(np.loadtxt(out, delimiter=",", skiprows=1), [[0.0, 0.7], [0.4, 0.3]], atol=1e-15)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--out", "{d}/p.txt"], "suffix"),
        (["--out", "{d}/missing/p.csv"], "does not exist"),
        (["--out", "{d}/dir.csv"], "is a directory"),
        ([], "--q-file needs --out"),
        (["--out", "{d}/p.csv", "--q", "0", "0"], "not both"),
    ],
)
def test_cli_refuses_bad_outputs_before_reading(tmp_path, capsys, args, message):
    q = tmp_path / "q.csv"
    q.write_text("nan,0\n")  # would fail too, but the output is checked first
    (tmp_path / "dir.csv").mkdir()
    code = main(["fk", "scara", "--q-file", str(q), *[a.format(d=tmp_path) for a in args]])
    assert code == 2 and message in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir.csv", "q.csv"]


@pytest.mark.parametrize(
    ("content", "message"),
    [("1,2,3\n", "rows of 2 values"), ("0.1,nan\n", "must be finite"), ("a,b\nc,d\n", "cannot read"), ("", "non-empty")],
)
def test_cli_refuses_bad_q_files(tmp_path, capsys, content, message):
    q, out = tmp_path / "q.csv", tmp_path / "p.csv"
    q.write_text(content)
    assert main(["fk", "scara", "--q-file", str(q), "--out", str(out)]) == 2
    assert message in capsys.readouterr().err and not out.exists()


def test_cli_out_without_q_file_names_the_missing_q_file(tmp_path, capsys):
    # --q with --out but no --q-file: the error is the missing --q-file, not a clash with it
    out = tmp_path / "p.csv"
    assert main(["fk", "scara", "--q", "0", "0", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "give --q-file" in err and "not both" not in err and err.count("\n") == 1
    assert not out.exists()
