"""Mobility three ways, on both robots and on small mechanisms built to make them disagree."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from kinematics.analyses import mobility as mob
from kinematics.generic.closedloop import ClosedLoop
from kinematics.mechanisms.p2us import closed_form as par
from kinematics.mechanisms.p2us.urdf import joint_values_at
from kinematics.model.robot import load_robot

from .test_cli import run, run_json
from .test_closedloop import workspace_poses
from .test_parallel import type_two_pose

MODELS = Path(__file__).parent / "models"


@pytest.fixture(scope="module")
def p2us_ref(p2us):
    return ClosedLoop(p2us).reference


def test_p2us_grubler(p2us, p2us_ref):
    g = mob.grubler(p2us, p2us_ref)
    assert (g.links, g.joints, g.freedoms, g.lam, g.mobility) == (11, 15, 33, 6, 3)  # paper B eqs. 1-2
    assert g.as_dict()["joint_types"] == {"P": 3, "U": 6, "S": 6}


def test_p2us_numeric(p2us, p2us_ref):
    n = mob.numeric_mobility(p2us, p2us_ref)
    assert (n.nv, n.constraints, n.rank, n.mobility) == (18, 15, 15, 3)
    assert n.platform_freedoms == 3 and n.idle == 0 and n.locked_platform_freedoms == 0


def test_p2us_screw_one_couple_per_limb(p2us, p2us_params, rng):
    P = p2us_params
    for p, _ in zip(*workspace_poses(P, 5, rng), strict=True):
        values = joint_values_at(P, p)
        s = mob.screw_analysis(p2us, p2us.configuration([values[n] for n in p2us.joint_names]))
        assert [lb.paths for lb in s.limbs] == [2, 2, 2]
        assert all(len(lb.wrenches) == 1 and lb.wrenches[0].type == "couple" for lb in s.limbs)
        assert s.constraint_rank == 3 and (s.translations, s.rotations) == (3, 0)
        # each couple is normal to its parallelogram's plane: axis parallel to t_i x n_i
        limbs = par.limb_ik(P, p)
        for i, lb in enumerate(s.limbs):
            normal = np.cross(P.t[i], limbs.n[i, 1])
            normal /= np.linalg.norm(normal)
            assert abs(abs(lb.wrenches[0].axis @ normal) - 1) <= 1e-9


def test_parallelogram_sub_chains_must_share_the_slider(p2us, p2us_ref):
    # Each rod alone (slider + U + S) spans all six twists: no constraint at all. Only the two
    # rods moving with one slider rate leave the couple.
    graph = mob.joint_graph(p2us, p2us_ref)
    limb = mob.screw_analysis(p2us, p2us_ref).limbs[1]
    edges = [e for e in graph.edges if e.name in limb.joints]
    for path in mob._paths(edges, 0, graph.platform):
        cols = [d for e, _ in path for d in e.dofs]
        assert np.linalg.matrix_rank(graph.twists[:, cols], tol=1e-9) == 6
    assert limb.twist_rank == 5


def test_scara(scara):
    rep = mob.analyse(scara, scara.configuration([0.3, 1.0]))
    assert rep.grubler.planar and rep.grubler.lam == 3 and rep.grubler.mobility == 2
    assert (rep.grubler.links, rep.grubler.joints) == (3, 2)
    assert rep.numeric.mobility == 2 and rep.numeric.platform_freedoms == 2
    assert (rep.screw.translations, rep.screw.rotations) == (1, 1)  # the tool link: turn about z + slide
    assert rep.notes == ()


def test_serial_spatial_arm(ur5):
    rep = mob.analyse(ur5, ur5.configuration([0.1, -1.0, 1.0, 0.2, 0.3, 0.1]))
    assert rep.grubler.mobility == 6 and rep.numeric.mobility == 6
    assert (rep.screw.translations, rep.screw.rotations) == (3, 3)


def test_planar_four_bar():
    robot = load_robot(MODELS / "fourbar.urdf")
    rep = mob.analyse(robot, ClosedLoop(robot).reference)
    assert rep.grubler.planar and rep.grubler.mobility == 1 and rep.numeric.mobility == 1
    assert rep.numeric.rank == 2  # the point closure's out-of-plane equation is redundant
    assert rep.notes == ()


def test_grubler_fails_on_a_planar_sub_loop():
    robot = load_robot(MODELS / "turntable_parallelogram.urdf")
    loop = ClosedLoop(robot)
    for q in (loop.reference, loop.solve([0.1, 0.2]).q):
        rep = mob.analyse(robot, q)
        assert not rep.grubler.planar and rep.grubler.mobility == 1
        assert rep.numeric.mobility == 2 and rep.numeric.platform_freedoms == 2
        assert any("Grübler-Kutzbach gives 1" in n and "redundant" in n for n in rep.notes)


def test_idle_spin_of_an_ss_coupler():
    robot = load_robot(MODELS / "rssr.urdf")
    rep = mob.analyse(robot, ClosedLoop(robot).reference)
    assert rep.grubler.mobility == 2 and rep.numeric.mobility == 2
    assert rep.numeric.platform_freedoms == 1 and rep.numeric.idle == 1
    assert (rep.screw.translations, rep.screw.rotations) == (0, 1)
    assert any("idle" in n for n in rep.notes)


def test_rssr_dead_centre_is_reported():
    robot = load_robot(MODELS / "rssr.urdf")
    loop = ClosedLoop(robot)
    values = np.zeros(robot.nv)
    values[robot.joint_names.index("s_y")] = -np.pi / 4  # crank along x, rocker up: a dead centre
    q = robot.configuration(values)
    assert np.abs(loop.residual(q)[0]).max() <= 1e-12
    rep = mob.analyse(robot, q)
    assert rep.numeric.platform_freedoms == 0 and rep.numeric.idle == 2


def test_p2us_type_two_pose_is_reported(p2us, p2us_params):
    p, _ = type_two_pose(p2us_params)
    values = joint_values_at(p2us_params, p)
    rep = mob.analyse(p2us, p2us.configuration([values[n] for n in p2us.joint_names]))
    assert rep.numeric.locked_platform_freedoms >= 1
    assert any("actuators locked" in n for n in rep.notes)


def test_cli_json(capsys):
    code, data, _ = run_json(capsys, "mobility", "p2us")
    assert code == 0
    assert {k: data["grubler"][k] for k in ("links", "joints", "freedoms")} == {"links": 11, "joints": 15, "freedoms": 33}
    assert data["numeric"]["mobility"] == 3
    screw = data["screw"]
    assert (screw["translations"], screw["rotations"]) == (3, 0)
    assert [w["type"] for w in screw["constraint_wrenches"]] == ["couple"] * 3
    assert all(len(w["axis"]) == 3 for w in screw["constraint_wrenches"])
    code, data, _ = run_json(capsys, "mobility", "p2us", "--position", "0.05", "0", "-0.45")
    assert code == 0 and data["screw"]["translations"] == 3
    code, data, _ = run_json(capsys, "mobility", "p2us", "--q", "0.25", "0.25", "0.2")
    assert code == 0 and data["numeric"]["platform_freedoms"] == 3
    code, data, _ = run_json(capsys, "mobility", "scara", "--q", "0.3", "1.0")
    assert data["grubler"]["mobility"] == 2
    code, out, _ = run(capsys, "mobility", str(MODELS / "turntable_parallelogram.urdf"))
    assert code == 0 and "notes:" in out and "redundant" in out


def test_cli_bad_input(capsys):
    code, out, err = run(capsys, "mobility", "p2us", "--position", "0", "0", "0.5")
    assert code == 1 and "cannot reach" in out and err == ""  # unreachable: an answer, as in ik
    for argv, needle in [
        (["mobility", "scara", "--position", "0", "0", "0"], "serial"),
        (["mobility", "p2us", "--q", "0.3"], "3 actuated"),
        (["mobility", "p2us", "--position", "0", "0", "-0.45", "--q", "0.2", "0.2", "0.2"], "not both"),
        (["mobility", "p2us", "--position", "0", "0", "-0.45", "--mode", "x"], "unknown mode"),
    ]:
        code, out, err = run(capsys, *argv)
        assert code == 2 and needle in err and err.count("\n") == 1, (argv, err)


def test_serial_default_is_regular_and_singular_poses_are_flagged(ur5, capsys):
    """Defect 8: UR5's default used to be q = 0 (the middle of +/-2 pi ranges), a singular pose,
    reported as 5 platform freedoms and an 'idle' joint. Oracle for (ir)regularity: the rank of
    a central-difference tool Jacobian (test_serial._fd_jacobian, FK only); a regular pose's
    sixth singular value is > 1e-3 of the first, a singular one's ~ the FD error (1e-8)."""
    from .test_serial import _fd_jacobian

    reg = mob.regular_configuration(ur5)
    assert np.all(ur5.within_limits(reg.values)) and reg.generic_rank == 6
    s = np.linalg.svd(_fd_jacobian(ur5, reg.values), compute_uv=False)
    assert s[5] / s[0] > 1e-3
    code, data, _ = run_json(capsys, "mobility", "ur5")
    assert code == 0 and data["numeric"]["platform_freedoms"] == 6
    assert data["numeric"]["idle"] == 0 and data["numeric"]["redundant"] == 0 and data["notes"] == []
    # q = 0 is singular (independently: the FD Jacobian loses a rank), and is flagged as such
    s0 = np.linalg.svd(_fd_jacobian(ur5, np.zeros(6)), compute_uv=False)
    assert s0[5] / s0[0] < 1e-7
    rep = mob.analyse(ur5, ur5.configuration(np.zeros(6)))
    assert rep.numeric.platform_freedoms == 5 and rep.numeric.idle == 0 and rep.numeric.redundant == 1
    assert any(n.startswith("singular configuration") for n in rep.notes)
    assert not any("idle" in n for n in rep.notes)


def test_surplus_freedoms_of_a_serial_arm_are_redundant():
    panda = load_robot("panda")
    rep = mob.analyse(panda, mob.regular_configuration(panda).q)
    assert rep.numeric.redundant == panda.nv - 6 and rep.numeric.idle == 0
    assert any("redundant" in n and "by design" in n for n in rep.notes)
    assert not any("idle" in n or "singular" in n for n in rep.notes)
