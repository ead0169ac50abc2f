"""A planar five-bar, loaded from a Gepetto-format robot.yaml, held to its closed forms through the
generic path (ClosedLoop solve, constrained Jacobian, mobility).

Tolerances. The loop solver stops at a closure error of 1e-12 m (closedloop.TOLERANCE). At poses
whose singularity indices (tests/fivebar.py) are >= 0.2 the tip and joint errors are at most that
error times the inverse of the index, <= 5e-12; 1e-10 leaves a factor 20. The constrained Jacobian
and the closed-form J_x^-1 J_q are both exact at the same configuration; their difference is
round-off amplified by the same conditioning (~1e-15 / 0.2^2), so 1e-10 again.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from kinematics.analyses import mobility as mob
from kinematics.errors import SingularConfigurationError
from kinematics.generic.closedloop import ClosedLoop
from kinematics.model.robot import load_robot

from .fivebar import FiveBar, circles, u

FIXTURE = Path(__file__).parent / "models" / "fivebar_gepetto"
REFERENCE_MODES = (1, -1)  # working mode of the fixture's all-zero (CAD) pose
ASSEMBLY = 1  # its assembly mode
TOL = 1e-10


@pytest.fixture(scope="module")
def robot():
    return load_robot(FIXTURE / "robot.urdf")


@pytest.fixture(scope="module")
def loop(robot):
    return ClosedLoop(robot)


@pytest.fixture(scope="module")
def five(robot):
    return FiveBar.from_robot(robot)


def regular_poses(five, n, rng, modes=REFERENCE_MODES, index=0.2):
    """(theta, P) pairs with both singularity indices >= `index`, in working mode `modes`."""
    out = []
    while len(out) < n:
        P = rng.uniform([-0.05, 0.22], [0.25, 0.45])
        theta = five.ik(P, modes)
        if theta is not None and min(five.singularity_indices(theta, P)) >= index:
            out.append((theta, P))
    return out


def values(robot, joints):
    return np.array([joints[n] for n in robot.joint_names])


def test_gepetto_file_becomes_the_loop_description(robot, five):
    assert robot.loops is not None and robot.loops.path.name == "robot.yaml"
    assert robot.loops.actuated == ("mot1", "mot2") and robot.loops.end_effector == "effector"
    assert [(c.frame1, c.frame2, c.type) for c in robot.loops.closures] == [("closedloop1_A", "closedloop1_B", "6d")]
    # geometry read back from the model: the fixture's documented dimensions
    np.testing.assert_allclose(five.a, [0.25, 0.22], atol=1e-15)
    np.testing.assert_allclose(five.b, [0.3, 0.32], atol=1e-15)


def test_fk_matches_closed_form(robot, loop, five, rng):
    worst = 0.0
    for theta, P in regular_poses(five, 30, rng):
        motors = theta - five.theta0
        sol = loop.solve(motors)
        assert sol.residual <= 1e-12
        expected = five.fk(motors, ASSEMBLY)
        worst = max(worst, float(np.linalg.norm(sol.pose.translation[:2] - expected)))
        assert abs(sol.pose.translation[2]) <= 1e-15
        # the same pose reached in the other assembly mode is a distinct, valid closed-form answer
        other = five.fk(motors, -ASSEMBLY)
        assert np.linalg.norm(other - expected) > 1e-3
    assert worst <= TOL  # measured 8.6e-13 m (the closure tolerance, amplified by the conditioning)


def test_four_working_modes_close_pinocchio_loop(robot, loop, five, rng):
    """Closed-form IK in all four working modes, set as Pinocchio configurations: the generic
    constraint residual vanishes, the tree FK puts the effector at P, and Newton started 0.05 rad
    away on the passive joints returns to the closed-form passive angles."""
    P = np.array([0.1, 0.33])
    seen = 0
    for modes in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        theta = five.ik(P, modes)
        assert theta is not None
        joints = five.joint_values(theta, P)
        q = robot.configuration(values(robot, joints))
        e, _ = loop.residual(q)
        assert np.abs(e).max() <= 1e-13  # closed forms in double precision: ~1e-16 m
        sol = loop.solve(theta - five.theta0, q0=robot.configuration(values(robot, joints) + 0.05 * np.array(
            [0, 1, 0, 1, 1])))
        np.testing.assert_allclose(sol.pose.translation[:2], P, atol=TOL)
        np.testing.assert_allclose(sol.values, values(robot, joints), atol=TOL)
        seen += 1
    assert seen == 4


def test_constrained_jacobian_matches_closed_form(robot, loop, five, rng):
    worst = 0.0
    for theta, P in regular_poses(five, 30, rng):
        q = robot.configuration(values(robot, five.joint_values(theta, P)))
        G = loop.constrained_jacobian(q)
        expected = five.twist(theta, P)
        worst = max(worst, float(np.abs(G[[0, 1, 5]] - expected).max()))
        assert np.abs(G[2:5]).max() <= 1e-15  # planar: no v_z, w_x, w_y
    assert worst <= TOL  # measured 2.1e-15


def test_type_two_singularity_is_refused(robot, loop, five):
    """Distal links aligned (B_1, P, B_2 collinear): the tip moves with the motors locked."""
    theta1 = five.theta0[0] + 0.1
    B1 = five.A[0] + five.a[0] * u(theta1)
    B2 = circles(five.A[1], five.a[1], B1, five.b[0] + five.b[1], 1)
    theta = np.array([theta1, np.arctan2(*(B2 - five.A[1])[::-1])])
    P = B1 + five.b[0] * (B2 - B1) / np.linalg.norm(B2 - B1)
    assert five.singularity_indices(theta, P)[1] <= 1e-12
    q = robot.configuration(values(robot, five.joint_values(theta, P)))
    assert np.abs(loop.residual(q)[0]).max() <= 1e-13
    with pytest.raises(SingularConfigurationError, match="type II"):
        loop.constrained_jacobian(q)
    rep = mob.analyse(robot, q)
    assert rep.numeric.locked_platform_freedoms == 1


def test_type_one_singularity_loses_a_tip_direction(robot, loop, five):
    """Chain 1 stretched (P on circle(A_1, a_1 + b_1)): det J_q = 0, and the generic constrained
    Jacobian's tip block drops rank: sigma_min / sigma_max ~ round-off."""
    P = five.A[0] + (five.a[0] + five.b[0]) * u(1.2)
    theta = five.ik(P, REFERENCE_MODES)
    assert theta is not None and five.singularity_indices(theta, P)[0] <= 1e-7
    q = robot.configuration(values(robot, five.joint_values(theta, P)))
    s = np.linalg.svd(loop.constrained_jacobian(q)[:2], compute_uv=False)
    assert s[1] <= 1e-7 * s[0]  # the closed form's det J_q / |J_q| at this pose is <= 1e-7
    assert s[0] > 0.1


def test_mobility_is_two(robot, loop, five, rng):
    theta, P = regular_poses(five, 1, rng)[0]
    q = robot.configuration(values(robot, five.joint_values(theta, P)))
    rep = mob.analyse(robot, q)
    # Regression: a 6d closure made the count spatial (lambda = 6, M = -1) although every axis is
    # parallel; a weld keeps a planar mechanism planar.
    assert rep.grubler.planar and rep.grubler.lam == 3 and rep.grubler.mobility == 2
    assert rep.numeric.mobility == 2 and rep.numeric.rank == 3  # 3 of the weld's 6 rows are redundant
    assert rep.numeric.platform_freedoms == 2 and rep.numeric.locked_platform_freedoms == 0
    assert rep.notes == ()


def test_point_closure_with_a_fixed_joint_agrees(tmp_path, robot, loop, five, rng):
    """The same five-bar closed by a 3D pair instead, with the welding revolute free3 locked by a
    FIXED substitution: same poses, same Jacobian, four joints, mobility 2."""
    shutil.copy(FIXTURE / "robot.urdf", tmp_path / "robot.urdf")
    (tmp_path / "robot.yaml").write_text(
        "closed_loop: [['closedloop1_A', 'closedloop3D_B']]\ntype: ['3d']\nname_mot: ['mot1', 'mot2']\n"
        "joint_name: ['free3']\njoint_type: ['FIXED']\n")
    point = load_robot(tmp_path / "robot.urdf")
    assert point.joint_names == ("mot1", "free1", "mot2", "free2")
    pl = ClosedLoop(point)
    for theta, P in regular_poses(five, 5, rng):
        motors = theta - five.theta0
        a, b = loop.solve(motors), pl.solve(motors)
        np.testing.assert_allclose(b.pose.translation, a.pose.translation, atol=TOL)
        np.testing.assert_allclose(pl.constrained_jacobian(b.q), loop.constrained_jacobian(a.q), atol=TOL)
    rep = mob.analyse(point, pl.reference)
    assert rep.grubler.planar and rep.grubler.mobility == 2 and rep.numeric.mobility == 2
    assert rep.numeric.rank == 2  # the point closure's out-of-plane row is redundant


def test_actuator_unit_follows_the_actuated_joints(robot):
    # the generic closed loop's J has one column per actuator: its unit is rad when every actuator
    # is revolute (this five-bar) and m when every one is prismatic (the p2us's sliders), so
    # dexterity must not report the "J mixes m and rad columns" note for either
    from kinematics.analyses.dexterity import dexterity
    from kinematics.mechanisms.closed_loop.mechanism import GenericClosedLoop

    mech = GenericClosedLoop(robot)
    assert mech.actuator_unit == "rad"
    assert GenericClosedLoop(load_robot("p2us")).actuator_unit == "m"
    d = dexterity(mech, samples=16, replicates=2, seed=0).as_dict()
    assert not d["mixed_units"] and d["yoshikawa_unit"] == "m^2/rad^2"


def test_cli_fk_closes_where_mobility_does(capsys, robot):
    # at actuator values [2, -2] the continuation from the fixture's pose gets stuck, but the loops
    # close with the actuators held (another assembly mode): mobility analyses that pose, so fk and
    # jacobian answer there too, saying how it was reached, instead of "no assembly there"
    import json

    from kinematics.cli import main

    argv = ["--q", "2", "-2", "--json"]
    assert main(["mobility", str(FIXTURE), *argv]) == 0
    capsys.readouterr()
    assert main(["fk", str(FIXTURE), *argv]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["q"] == pytest.approx([2, -2], abs=1e-12) and d["residual"] <= 1e-12  # the solver's tolerance
    assert "actuators held" in d["configuration"]
    values = np.array([d["joint_values"][n] for n in robot.joint_names])
    assert np.abs(ClosedLoop(robot).residual(robot.configuration(values))[0]).max() <= 1e-10  # closed (TOL)
    assert main(["jacobian", str(FIXTURE), *argv]) == 0


def test_cli_mobility_says_the_actuator_values_it_used(capsys):
    # --degrees: the report gives the values analysed, in rad, not the numbers typed
    import json

    from kinematics.cli import main

    assert main(["mobility", str(FIXTURE), "--q", "20", "20", "--degrees", "--json"]) == 0
    where = json.loads(capsys.readouterr().out)["configuration"]
    assert where.startswith("actuators at [0.34906585, 0.34906585] rad"), where


def test_cli_ik_finds_the_actuator_values_fk_was_given(capsys, robot):
    # `kinematics ik` of a generic closed loop (the batched solver; it refused every robot without
    # closed forms): at fk's point of actuator values q, q is among the solutions (to the loops'
    # closure tolerance, 1e-12 m, over the five-bar's ~0.1 m links: 1e-9 rad leaves margin); a far
    # point is an answer, exit 1; a range the solutions break is named in their violations
    import json

    from kinematics.cli import main

    q = [0.3, -0.4]
    assert main(["fk", str(FIXTURE), "--q", *map(str, q), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    from kinematics.mechanisms import mechanism_of

    axes = [k for k, name in enumerate("xyz") if name in mechanism_of(robot).task_axes]
    point = [str(d["position"][k]) for k in axes]
    assert main(["ik", str(FIXTURE), "--position", *point, "--json"]) == 0
    ik = json.loads(capsys.readouterr().out)
    assert ik["reachable"] and ik["actuators"] == list(robot.loops.actuated)
    assert min(np.abs(np.array(s["q"]) - q).max() for s in ik["solutions"]) <= 1e-9
    assert main(["ik", str(FIXTURE), "--position", "5", "5"]) == 1
    assert "NOT reachable" in capsys.readouterr().out
    name = robot.loops.actuated[0]
    assert main(["ik", str(FIXTURE), "--range", f"{name}=1.0:1.1", "--position", *point, "--json"]) == 1
    broken = json.loads(capsys.readouterr().out)
    assert broken["solutions"] and all(not s["within_limits"] and any(v.startswith(f"{name} = ") for v in s["violations"])
                                       for s in broken["solutions"])


def test_a_single_query_finds_the_modes_a_cold_start_misses(robot, five):
    """At (0.2109375, -0.21875) every start a cold single point gets (the atlas starts; restarts are
    not spent where no slot of a block closed) misses all four working modes, and `kinematics ik`
    said "NOT reachable": a query of a few points is continued from the reference position
    (`GenericClosedLoop._search`), which finds each mode the closed forms give, to the closure
    tolerance (1e-12 m over ~0.1 m links: 1e-9 rad leaves margin)."""
    from kinematics.generic.loop_batch import LoopBatch
    from kinematics.mechanisms import mechanism_of

    p = np.array([0.2109375, -0.21875])
    assert not LoopBatch.from_robot(robot).ik(p[None], warm=False).found.any()  # the case: cold, nothing
    mech = mechanism_of(robot)
    res = mech.ik(p[None])
    found = res.q[0, res.reachable[0]]
    for m in [(1, 1), (1, -1), (-1, 1), (-1, -1)]:
        theta = five.ik(p, m)
        assert theta is not None
        values = five.joint_values(theta, p)
        want = np.array([values[n] for n in robot.loops.actuated])  # the actuators' joint values
        assert np.min(np.abs(np.angle(np.exp(1j * (found - want)))).max(axis=1)) <= 1e-9, m
