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

from .conftest import GEPETTO
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
    for path in mob.simple_paths(edges, 0, graph.platform):
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


# -- the platform's freedoms against finite differences of the closure solver ------------------
needs_gepetto = pytest.mark.skipif(not GEPETTO.is_dir(), reason=f"{GEPETTO} absent (Gepetto's example-parallel-robots)")

FD_STEP = 1e-4
"""Actuator step of the central differences [rad]."""

FD_SOLVE_TOL = 1e-14
"""Closure tolerance of the re-solves [m]: its error in a difference quotient, tol / FD_STEP = 1e-10
m/rad, is below 2e-8 of the smallest twist of the models here once scaled by L."""

FD_SIN_TOL = 1e-6
"""Largest sin(principal angle) between the classified and the finite-difference twist spaces,
both as (v_E / L; w). Central differences err by ~c h^2: measured 3.2e-6 at h = 1e-3 and 3.2e-8 at
1e-4 for the five-bar (the h^2 law, c = 3.2), 1.5e-9 for the four-bar, 7e-11 for robot_delta;
the solver's share is <= 2e-8 (FD_SOLVE_TOL) and the analysis's own (a pose closed to 1e-12 m)
~2e-8 (mobility.TRANSLATION_RTOL). 1e-6 is 30 times above the largest."""


def _fd_twists(robot, q: np.ndarray) -> tuple[np.ndarray, float]:
    """Central-difference end-effector twists (v_E; w) [m/rad; rad/rad], one column per actuator
    (re-solving the loops from q) or per joint (a serial arm), and the largest rotation of the end
    effector between q and a stepped pose [rad]."""
    import pinocchio as pin

    def pose(values):
        if robot.loops is None:
            data = robot.model.createData()
            pin.framesForwardKinematics(robot.model, data, robot.configuration(values))
            return data.oMf[robot.frame_id()]
        return loop.solve(values, q0=q, tol=FD_SOLVE_TOL).pose

    loop = ClosedLoop(robot) if robot.loops is not None else None
    values = robot.values_from_configuration(q)
    a0 = values[loop.actuated_dofs] if loop is not None else values
    R0 = pose(a0).rotation
    cols, turn = [], 0.0
    for i in range(len(a0)):
        step = np.zeros(len(a0))
        step[i] = FD_STEP
        plus, minus = pose(a0 + step), pose(a0 - step)
        turn = max(turn, *(np.linalg.norm(pin.log3(P.rotation @ R0.T)) for P in (plus, minus)))
        cols.append(np.concatenate([(plus.translation - minus.translation) / (2 * FD_STEP),
                                    pin.log3(plus.rotation @ minus.rotation.T) / (2 * FD_STEP)]))
    return np.array(cols).T, turn


def _classified_twists(s: mob.ScrewAnalysis, E: np.ndarray) -> np.ndarray:
    """The twists (v_E; w) the classified freedoms stand for."""
    cols = [np.r_[f.axis, 0, 0, 0] if f.type == "translation"
            else np.r_[np.cross(f.axis, E - f.point) + f.pitch * f.axis, f.axis] for f in s.freedoms]
    return np.array(cols).T.reshape(6, -1)


def _sin_max(A: np.ndarray, B: np.ndarray) -> float:
    """sin of the largest principal angle between the column spaces of A and B (equal ranks)."""
    Qa = np.linalg.svd(A, full_matrices=False)[0][:, : A.shape[1]]
    Qb = np.linalg.svd(B, full_matrices=False)[0][:, : B.shape[1]]
    return float(np.linalg.norm(Qb - Qa @ (Qa.T @ Qb), 2))


def _check_against_fd(robot, q: np.ndarray) -> tuple[mob.ScrewAnalysis, float]:
    """Screw analysis at q, its twist space and point directions held against finite differences."""
    from kinematics.generic.serial import forward_kinematics

    s = mob.screw_analysis(robot, q)
    E = forward_kinematics(robot, q).position
    T, turn = _fd_twists(robot, q)
    scale = np.diag([1 / s.length] * 3 + [1.0] * 3)  # (v_E / L; w): both rates [rad/s]
    fd_rank = int(np.sum(np.linalg.svd(scale @ T, compute_uv=False) > FD_SIN_TOL))
    assert len(s.freedoms) == fd_rank
    assert _sin_max(scale @ _classified_twists(s, E), scale @ T) <= FD_SIN_TOL
    point = np.array(s.point_axes).T.reshape(3, -1)
    assert point.shape[1] == int(np.sum(np.linalg.svd(T[:3] / s.length, compute_uv=False) > FD_SIN_TOL))
    if point.shape[1]:
        assert _sin_max(point, T[:3]) <= FD_SIN_TOL
    return s, turn


@needs_gepetto
def test_robot_delta_translates():
    """Issue 32: robot_delta (planar Delta, parallelograms) was reported as 1 translation and 1
    rotation about an axis 5.4e6 m away. Its platform only translates: the solver's finite
    differences turn it by ~1e-13 rad per 1e-4 rad actuator step (1e-9: the solver's noise, far
    below the 2.3e-4 rad a five-bar's distal link turns over the same step)."""
    robot = load_robot(GEPETTO / "robot_delta" / "robot.urdf")
    q = ClosedLoop(robot).solve(np.zeros(2)).q
    s, turn = _check_against_fd(robot, q)
    assert (s.translations, s.rotations, s.point_translations) == (2, 0, 2)
    assert turn <= 1e-9
    assert all(f.axis[0] == 0 for f in s.freedoms)  # in the y-z plane (its joints turn about x)
    # The limbs' constraint wrenches, dually: the parallelogram limb holds the platform's three
    # rotations (couples) and its x translation (a force along x); the 3R limb, planar about x,
    # two out-of-plane couples and the x force. The old split called the in-plane couple a force
    # along a line 3.2e6 m away.
    kinds = [sorted(w.type for w in lb.wrenches) for lb in s.limbs]
    assert kinds == [["couple"] * 3 + ["force"], ["couple"] * 2 + ["force"]]
    assert _max_work(s, robot, q) <= FD_SIN_TOL


def _max_work(s: mob.ScrewAnalysis, robot, q: np.ndarray) -> float:
    """Largest |W . T| / (L |W~| |T~|) of a reported constraint wrench W (rebuilt from its type,
    axis and point) on a finite-difference twist T, both scaled ((f; m_E / L), (v_E / L; w)):
    0 for a wrench reciprocal to every motion the solver finds."""
    from kinematics.generic.serial import forward_kinematics

    E = forward_kinematics(robot, q).position
    T, _ = _fd_twists(robot, q)
    L = s.length
    worst = 0.0
    for w in (w for lb in s.limbs for w in lb.wrenches):
        W = np.r_[0, 0, 0, w.axis] if w.type == "couple" else np.r_[w.axis, np.cross(w.point - E, w.axis)]
        for t in T.T:
            work = W[:3] @ t[:3] + W[3:] @ t[3:]
            norm = L * np.linalg.norm(np.r_[W[:3], W[3:] / L]) * np.linalg.norm(np.r_[t[:3] / L, t[3:]])
            worst = max(worst, abs(work) / norm)
    return worst


@needs_gepetto
def test_five_bar_tip_translates_its_body_turns():
    """5bar_linkage: the end effector sits on the distal link, which turns: the body has a
    translation and a rotation, the tip point two translations."""
    robot = load_robot(GEPETTO / "5bar_linkage" / "robot.urdf")
    s, turn = _check_against_fd(robot, ClosedLoop(robot).solve(np.array([0.3, 1.0])).q)
    assert (s.translations, s.rotations, s.point_translations) == (1, 1, 2)
    assert turn > 1e-5


def test_four_bar_coupler_rotates_about_its_instant_centre():
    """The coupler of a four-bar turns about the instantaneous centre (the crank and rocker lines
    meet there): the FD twist holds the reported axis point and zero pitch."""
    robot = load_robot(MODELS / "fourbar.urdf")
    s, turn = _check_against_fd(robot, ClosedLoop(robot).reference)
    assert (s.translations, s.rotations, s.point_translations) == (0, 1, 1)
    assert s.freedoms[0].pitch == 0.0 and turn > 1e-6


def test_pendulum_rotates_about_its_hinge():
    robot = load_robot(MODELS / "pendulum.urdf")
    s, _ = _check_against_fd(robot, robot.configuration([0.4]))
    (f,) = s.freedoms
    assert f.type == "rotation" and f.pitch == 0.0
    assert np.allclose(f.axis, [0, 0, 1], rtol=0, atol=1e-15)
    assert np.allclose(f.point, [0, 0, 0.1], rtol=0, atol=1e-15)  # the hinge: the axis point nearest the tool


def test_translation_threshold_is_scale_and_origin_free():
    """A rotation whose axis is d from the end-effector point E is a translation iff d > L /
    TRANSLATION_RTOL, and a force whose line is d from E a couple, wherever the model sits and
    whatever its size."""
    for L, origin in ((0.1, np.zeros(3)), (1.0, np.array([3e4, -2e4, 1e4])), (1e3, np.zeros(3))):
        E = origin + L * np.array([0.3, 0.1, -0.2])
        for factor, kind in ((1e-3, "rotation"), (1e-1, "rotation"), (10.0, "translation")):
            d = factor * L / mob.TRANSLATION_RTOL
            p = E + np.array([0.0, d, 0.0])  # axis z through p: E moves along x
            twist = np.r_[np.cross(p, [0, 0, 1.0]), 0, 0, 1]  # (v_O; w) = (p x w; w)
            (f,), axes = mob.classify_twists(twist[:, None], E, L)
            assert f.type == kind, (L, factor)
            assert np.allclose(axes, [[1, 0, 0]], rtol=0, atol=1e-12)
            if kind == "rotation":
                assert np.allclose(f.point, p, rtol=1e-9, atol=1e-9 * abs(origin).max(initial=L))
            wrench = np.r_[1.0, 0, 0, np.cross(p, [1.0, 0, 0])]  # (f; m_O): a force along x through p
            (w,) = mob.classify_wrenches(wrench[:, None], E, L)
            assert w.type == {"rotation": "force", "translation": "couple"}[kind], (L, factor)
            if w.type == "force":  # the line's point nearest E
                nearest = p + (E - p)[0] * np.array([1.0, 0, 0])
                assert np.allclose(w.point, nearest, rtol=1e-9, atol=1e-9 * abs(origin).max(initial=L))


FIXED_ONLY = """<robot name="fixed"><link name="base"/><link name="tip"/>
<joint name="j" type="fixed"><parent link="base"/><child link="tip"/><origin xyz="0.1 0 0"/></joint></robot>
"""


def test_cli_robot_without_degrees_of_freedom(capsys, tmp_path):
    # a robot of fixed joints only (its tool Jacobian is 6 x 0) is refused in one line, as
    # workspace-volume refuses it, not with a reshape error from the regular-pose search
    urdf = tmp_path / "fixed.urdf"
    urdf.write_text(FIXED_ONLY)
    code, out, err = run(capsys, "mobility", str(urdf))
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "no degree of freedom" in err
