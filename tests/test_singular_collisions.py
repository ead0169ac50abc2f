"""`singularities --collisions/--obstacles` on a planar arm: each singular configuration
(theta2 = 0, the arm stretched) flagged colliding or not, held to the wall's geometry by hand."""

from __future__ import annotations

import math

import numpy as np

from .test_cli import run_json
from .test_collision_obstacles import HALF, L1, L2, WALL, R, _obstacles, arm  # noqa: F401 (a fixture)


def test_stretched_arm_flags_are_the_walls_by_hand(arm, tmp_path, capsys):  # noqa: F811
    # stretched at theta1 the arm is one segment from the origin to (L1 + L2)(cos, sin)(theta1),
    # capsules of radius R: it reaches the wall x >= WALL iff (L1 + L2) cos(theta1) >= WALL - R
    _obstacles(tmp_path, HALF)
    urdf = str(tmp_path / "arm2r.urdf")
    code, d, err = run_json(capsys, "singularities", urdf, "--obstacles", str(tmp_path / "wall.yaml"))
    assert code == 0, err
    pts = [p for p in d["singular_points"] if p["type"] == "theta2 = 0"]
    theta1 = np.array([p["q"][0] for p in pts])
    want = (L1 + L2) * np.cos(theta1) >= WALL - R
    margin = np.abs((L1 + L2) * np.cos(theta1) - (WALL - R))
    clear = margin > 1e-9  # a point on the boundary itself is left out (rounding decides it)
    got = np.array([p["colliding"] for p in pts])
    assert clear.sum() > 0.9 * len(pts) and want[clear].any() and (~want[clear]).any()
    assert np.array_equal(got[clear], want[clear])
    c = d["collisions"]
    assert c["colliding_points"] == int(got.sum()) and c["obstacles"] == ["wall"]
    assert all(p["pair"][1] == "wall" or p["pair"][0] == "wall" for p in pts if p["colliding"])
    # the half-width of the colliding arc: acos((WALL - R) / (L1 + L2)), sampled at 1 degree
    half = math.acos((WALL - R) / (L1 + L2))
    assert abs(np.ptp(theta1[got]) / 2 - half) <= math.radians(1.0)
