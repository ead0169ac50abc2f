"""A base joint with a partial turn (a range L in [pi, 2 pi)): (L / 2 pi) x the full turn's solid
plus the profile integral of the circles' extents (`kinematics.mechanisms.serial.turn`,
`kinematics.analyses.columns.turned`) against volumes derived by hand for the revolved 3R test arm
with its base limited; and tool points of measure-zero reach (`SerialArm.measure_zero`)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from kinematics.analyses.workspace import measure_workspace
from kinematics.mechanisms.serial.mechanism import SerialArm
from kinematics.model.robot import load_robot
from tests.test_serial_workspace import revolved_volume_closed_form

MODELS = Path(__file__).parent / "models"
TURN = 0.75 * math.pi  # the base's limits +-TURN: L = 1.5 pi


def limited(tmp_path: Path, second_yaw: bool, second_range: float | None = None) -> Path:
    """tests/models/arm3r_revolved.urdf with its yaw limited to +-TURN; with `second_yaw`, a
    continuous yaw about the same axis right after it (the arm with its base held then still
    turns about the axis: every circle of the profile is covered), limited to +-second_range
    when given."""
    text = (MODELS / "arm3r_revolved.urdf").read_text()
    text = text.replace('<joint name="yaw" type="continuous">',
                        '<joint name="yaw" type="revolute">').replace(
        '<origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>',
        f'<origin xyz="0 0 0.1"/><axis xyz="0 0 1"/><limit lower="{-TURN!r}" upper="{TURN!r}" effort="1" '
        'velocity="1"/>', 1)
    if second_yaw:
        text = text.replace('<link name="turret"/>', '<link name="turret"/><link name="turret2"/>').replace(
            '<parent link="turret"/><child link="upper"/>', '<parent link="turret2"/><child link="upper"/>').replace(
            '<joint name="pitch"', '<joint name="yaw2" type="continuous"><parent link="turret"/>'
            '<child link="turret2"/><axis xyz="0 0 1"/></joint>\n  <joint name="pitch"', 1)
        if second_range is not None:
            text = text.replace('<joint name="yaw2" type="continuous">', '<joint name="yaw2" type="revolute">').replace(
                '<child link="turret2"/><axis xyz="0 0 1"/>', '<child link="turret2"/><axis xyz="0 0 1"/><limit lower='
                f'"{-second_range!r}" upper="{second_range!r}" effort="1" velocity="1"/>')
    path = tmp_path / (("arm4r_turn.urdf" if second_range is None else "arm4r_turn2.urdf") if second_yaw
                       else "arm3r_turn.urdf")
    path.write_text(text)
    return path


def test_covered_partial_turn_is_the_solid_of_revolution(tmp_path):
    """A second full-turn yaw covers every circle: the set is the full solid, V = Pappus's."""
    arm = SerialArm(load_robot(limited(tmp_path, True)))
    assert arm.reach.setup.mode == "revolved" and arm.reach.turn == pytest.approx((-TURN, TURN))
    exact = revolved_volume_closed_form(-0.5, 0.8, 0.3, 1.5)  # 0.3313338 m^3
    ws = measure_workspace(arm, step=0.05, rtol=1e-2, check=True)
    assert ws.result.converged and abs(ws.total - exact) <= ws.error <= 2e-2 * exact
    assert ws.result.fixed_error is not None  # the cover bound answered (no circle sampled)


def test_partial_turn_needs_a_rest_with_volume(tmp_path):
    """One azimuth per circle (the 2R arm moves in a plane through the axis): W0 has no volume, its
    circles' azimuths are isolated points that sampling cannot find (finger_edu's second posture
    in the near arc made the profile path 14 % low), so the arm is measured in space, not as a
    partial turn; the world margin holds the base within its limits (the sector's membership)."""
    arm = SerialArm(load_robot(limited(tmp_path, False)))
    assert arm.reach.turn is None and arm.reach.setup.mode == "spatial"
    # the world margin holds the base within its limits: the sector's membership
    rng = np.random.default_rng(3)
    az = rng.uniform(-math.pi, math.pi, 400)
    # the tip at yaw 0, pitch 0.1, elbow 0.9 (inside the profile), turned about the axis
    x, _, z = arm.fk(np.array([[0.0, 0.1, 0.9]])).p[0, 0]
    p = np.column_stack([x * np.cos(az), x * np.sin(az), np.full(400, z)])
    clear = np.abs(np.abs(az) - TURN) > 1e-6
    m = arm.margin()(p)[:, 0]
    np.testing.assert_array_equal((m >= 0)[clear], (np.abs(az) <= TURN)[clear])


def test_partly_covered_partial_turn(tmp_path):
    """A second yaw about the base axis within +-B = 0.3 rad: each circle's arc set S is an arc of
    extent 2 B (the 2R map is one-to-one), so W holds an arc L + 2 B of every circle of the profile:
    V = (L + 2 B) / 2 pi x V_full = 0.8455 V_full; X = (2 B / 2 pi) V_full is sampled on the near
    arcs (their ends bracketed) since the cover test fails everywhere (2 B < w = pi / 2)."""
    B = 0.3
    arm = SerialArm(load_robot(limited(tmp_path, True, B)))
    exact = (1.5 * math.pi + 2 * B) / (2 * math.pi) * revolved_volume_closed_form(-0.5, 0.8, 0.3, 1.5)
    ws = measure_workspace(arm, step=0.05, rtol=1e-2, check=True)  # (43 s at 2 cm and 1e-3: true error 8.7e-5 m^3)
    assert ws.result.converged, ws.unconverged()
    assert abs(ws.total - exact) <= ws.error <= 1e-2 * ws.total


def test_fewer_freedoms_than_the_task_is_measure_zero(tmp_path):
    """A tool point on the last joint's axis: example-robot-data's double pendulum (link2 on joint
    2's axis: a circle's arc in its plane, 1 freedom in 2-D) and the 3R arm's elbow link (on the
    elbow's axis: a patch of sphere, 2 freedoms in 3-D) reach sets of zero measure: an exact 0,
    converged, with the reason; the 3R arm's tip has all 3."""
    pendulum = SerialArm(load_robot("double_pendulum", ranges={"joint1": (-3.0, 3.0), "joint2": (-3.0, 3.0)}))
    ws = measure_workspace(pendulum, step=0.01, rtol=1e-3, check=True)
    assert ws.total == 0.0 and ws.error == 0.0 and ws.result.converged
    assert "1 freedom in a 2-D task space" in ws.as_dict()["measure_zero"] and "joint2 never moves it" in ws.measure_zero
    elbow = SerialArm(load_robot(MODELS / "arm3r_revolved.urdf", tool_frame="fore"))
    ws = measure_workspace(elbow, step=0.02, rtol=1e-3)
    assert ws.total == 0.0 and "2 freedoms in a 3-D task space" in ws.measure_zero and "a surface" in ws.measure_zero
    assert SerialArm(load_robot(MODELS / "arm3r_revolved.urdf")).measure_zero() is None


def test_a_measure_zero_reach_is_the_same_exact_zero_with_collisions(capsys):
    """With --collisions the double pendulum's reach (an arc: zero area) is the kinematic measure's
    exact 0, converged, with its reason: nothing to search, nothing to remove (it was a sampled
    "0, NOT converged"); the human reports name the reason instead of a sampling method."""
    from kinematics.analyses.collision_volume import measure_collision_workspace
    from tests.test_cli import run

    robot = load_robot("double_pendulum", ranges={"joint1": (-3.0, 3.0), "joint2": (-3.0, 3.0)})
    cw = measure_collision_workspace(SerialArm(robot), robot, step=0.05, rtol=0.05)
    assert cw.workspace.total == 0.0 and cw.workspace.error == 0.0 and cw.workspace.result.converged
    assert cw.kinematic == 0.0 and cw.removed == 0.0 and not cw.pairs
    assert "1 freedom in a 2-D task space" in cw.as_dict()["measure_zero"]
    ranges = ["--range", "joint1=-3:3", "--range", "joint2=-3:3", "--step", "0.05", "--rtol", "0.05"]
    for extra, line in ((["--collisions"], "zero measure"), ([], "none needed: the frame 'link2' has 1 freedom")):
        code, text, err = run(capsys, "workspace-volume", "double_pendulum", *ranges, *extra)
        assert code == 0 and line in text and "NOT converged" not in text and not err, (text, err)


def test_out_of_searches_is_not_converged_and_still_covers(tmp_path, monkeypatch):
    """The integral's budget counts reach searches (a point of an arc set costs 2 pi r / step of
    them): with 20 000 the partly covered arm (X exact, as above) stops after its first rounds,
    `converged` false, and the estimate still covers the exact volume; the run spends at most one
    round past the budget (each rule prices its next round before it halves)."""
    from kinematics.analyses.columns import turned

    monkeypatch.setattr(turned, "SEARCHES", 20_000)
    B = 0.3
    arm = SerialArm(load_robot(limited(tmp_path, True, B)))
    exact = (1.5 * math.pi + 2 * B) / (2 * math.pi) * revolved_volume_closed_form(-0.5, 0.8, 0.3, 1.5)
    ws = measure_workspace(arm, step=0.05, rtol=1e-2)
    assert not ws.result.converged and "search budget ran out" in ws.unconverged()["union"]
    assert abs(ws.total - exact) <= ws.error


def test_adaptive_rule_spends_a_cost_budget_where_the_error_is():
    """`adaptive_1d` with `cost`: sqrt(x) on [0, 1] (exact 2/3; its square-root end never lets a
    1e-13 tolerance converge) whose evaluations cost 100 each below x = 0.05 and 1 elsewhere (as
    a circle of searches against one search): the rule stops at the budget (each round priced at
    the dearer of the mean and the last round's cost per evaluation; measured 4.7 % over it, the
    last round's misprice), not converged, its estimate covering the true error; counted in
    evaluations, the same bound lets it spend 45x more."""
    from kinematics.analyses.columns.quadrature import adaptive_1d

    spent = [0]

    def f(_p: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        spent[0] += int(np.where(x < 0.05, 100, 1).sum())
        return np.sqrt(x)[:, None], np.zeros((len(x), 1)), np.zeros((len(x), 1), np.int64)

    a, b = np.zeros(1), np.ones(1)
    q, e, ok, _ = adaptive_1d(f, a, b, 1e-13, 0.0, pieces=4, max_evals=20_000, cost=lambda: spent[0])
    assert not ok[0] and spent[0] <= 1.1 * 20_000 and abs(q[0, 0] - 2 / 3) <= e[0, 0]
    spent[0] = 0
    adaptive_1d(f, a, b, 1e-13, 0.0, pieces=4, max_evals=20_000)
    assert spent[0] > 10 * 20_000
