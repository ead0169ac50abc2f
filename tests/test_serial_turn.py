"""A base joint with a partial turn (a range L in [pi, 2 pi)): the profile with the cover test
(`kinematics.mechanisms.serial.reach`, `Reach.cover`, `ReachMargin.finish`) against volumes
derived by hand for the revolved 3R test arm with its base limited."""

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


def limited(tmp_path: Path, second_yaw: bool) -> Path:
    """tests/models/arm3r_revolved.urdf with its yaw limited to +-TURN; with `second_yaw`, a
    continuous yaw about the same axis right after it (the arm with its base held then still
    turns about the axis: every circle of the profile is covered)."""
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
    path = tmp_path / ("arm4r_turn.urdf" if second_yaw else "arm3r_turn.urdf")
    path.write_text(text)
    return path


def test_covered_partial_turn_is_the_solid_of_revolution(tmp_path):
    """A second full-turn yaw covers every circle: the set is the full solid, V = Pappus's."""
    arm = SerialArm(load_robot(limited(tmp_path, True)))
    assert arm.reach.setup.mode == "revolved" and arm.reach.turn == pytest.approx((-TURN, TURN))
    exact = revolved_volume_closed_form(-0.5, 0.8, 0.3, 1.5)  # 0.3313338 m^3
    ws = measure_workspace(arm, step=0.05, rtol=1e-2, check=True)
    assert ws.result.converged and abs(ws.total - exact) <= ws.error <= 2e-2 * exact


def test_uncovered_partial_turn_is_within_its_bounds(tmp_path, capsys):
    """One azimuth per circle (the 2R arm moves in a plane through the axis): W is the sector of
    angle L of the solid, V = (L / 2 pi) V_full = 0.75 V_full. No circle is covered, so the
    estimate is the bounds' middle (1 - k) V_full with k = (1 - L / 2 pi) / 2 = 1/8, its error
    at least k V_full (at most that plus the quadrature's and the Monte-Carlo count's): the true
    volume, the lower bound, is within the estimate, which is not converged."""
    arm = SerialArm(load_robot(limited(tmp_path, False)))
    full = revolved_volume_closed_form(-0.5, 0.8, 0.3, 1.5)
    ws = measure_workspace(arm, step=0.05, rtol=1e-2, check=True)
    assert not ws.result.converged
    assert abs(ws.total - 0.75 * full) <= ws.error <= 0.16 * full
    assert ws.total == pytest.approx(0.875 * full, rel=1e-2)
    # the reason names the bound a finer step cannot shrink (k V_full alone is 12 % of the volume)
    assert "no finer step" in ws.unconverged()["union"]
    assert ws.result.fixed_error[-1] >= 0.125 * full * (1 - 0.05)  # k D, D ~ V_full (Monte Carlo, 5 %)
    from kinematics.cli import main

    assert main(["workspace-volume", str(limited(tmp_path, False)), "--step", "0.05", "--rtol", "1e-2"]) == 0
    assert "a smaller --step cannot help" in capsys.readouterr().err  # not "try a smaller --step"
    # the world margin holds the base within its limits: the sector's membership
    rng = np.random.default_rng(3)
    az = rng.uniform(-math.pi, math.pi, 400)
    # the tip at yaw 0, pitch 0.1, elbow 0.9 (inside the profile), turned about the axis
    x, _, z = arm.fk(np.array([[0.0, 0.1, 0.9]])).p[0, 0]
    p = np.column_stack([x * np.cos(az), x * np.sin(az), np.full(400, z)])
    clear = np.abs(np.abs(az) - TURN) > 1e-6
    m = arm.margin()(p)[:, 0]
    np.testing.assert_array_equal((m >= 0)[clear], (np.abs(az) <= TURN)[clear])
