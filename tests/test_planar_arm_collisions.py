"""Collisions of the planar arm (closed form) beyond its area: `singularities --obstacles` (each
singular configuration, theta2 = 0, flagged) and `show --workspace --obstacles` (the points where
both elbows collide drawn apart), held to the wall's geometry by hand."""

from __future__ import annotations

import math
import re

import numpy as np

from kinematics.analyses.collisions import collision_model_of
from kinematics.mechanisms import mechanism_of
from kinematics.views import meshcat as viz

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


def test_workspace_view_draws_where_both_elbows_hit_the_wall(arm, tmp_path, capsys):  # noqa: F811
    # a tool point P = rho (cos, sin)(phi) has its elbows at L1 (cos, sin)(phi -+ gamma),
    # cos(gamma) = (L1^2 + rho^2 - L2^2) / (2 L1 rho); the arm (capsules from the origin) is free in
    # a branch iff P and that elbow both have x < WALL - R, so every branch collides iff P.x >= c
    # or both elbows do
    obstacles = _obstacles(tmp_path, HALF)
    cm = collision_model_of(arm, obstacles, self_collisions=False)
    step = 0.023  # no grid column on the line x = WALL - R
    scene = viz.scara_view(arm, workspace=True, collisions=cm, step=step)
    mech = mechanism_of(arm)
    lo, hi = mech.bounding_box("all")
    axes = [np.arange(lo[k] + step / 2, hi[k], step) for k in range(2)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 2)
    rho, phi = np.hypot(pts[:, 0], pts[:, 1]), np.arctan2(pts[:, 1], pts[:, 0])
    inside = (rho >= L1 - L2) & (rho <= L1 + L2)
    pts, rho, phi = pts[inside], rho[inside], phi[inside]
    gamma = np.arccos(np.clip((L1 * L1 + rho * rho - L2 * L2) / (2 * L1 * rho), -1, 1))
    c = WALL - R
    elbow_x = L1 * np.cos(np.stack([phi - gamma, phi + gamma]))
    hits = (pts[:, 0] >= c) | (elbow_x >= c).all(axis=0)
    near = np.minimum(np.abs(pts[:, 0] - c), np.abs(elbow_x - c).min(axis=0))
    assert near.min() > 1e-9 and 0 < hits.sum() < len(pts)  # no grid point on a boundary
    labels = [label for label, _ in scene.legend]
    drawn = [int(m.group(1)) for m in (re.search(r"colliding: \S+ - wall binds \((\d+) points\)", x)
                                       for x in labels) if m]
    free = [int(m.group(1)) for m in (re.search(r"collision-free workspace \((\d+) points\)", x)
                                      for x in labels) if m]
    assert sum(drawn) == int(hits.sum()) and free == [int((~hits).sum())]
    assert "obstacle wall" in labels
    # `show`'s collisions block: the same counts, by hand
    code, d, err = run_json(capsys, "show", str(tmp_path / "arm2r.urdf"), "--workspace", "--obstacles",
                            str(tmp_path / "wall.yaml"), "--step", str(step), "--export", str(tmp_path / "s.html"))
    assert code == 0, err
    c = d["collisions"]
    assert (c["mode"], c["step_m"], c["grid_points"]) == ("planar", step, len(inside))
    assert (c["reached"], c["free"], c["colliding"]) == (len(pts), int((~hits).sum()), int(hits.sum()))
    assert sum(p["points"] for p in c["binding_pairs"]) == c["colliding"]
    assert all("wall" in p["links"] for p in c["binding_pairs"]) and c["obstacles"] == ["wall"]
    links = [tuple(p["links"]) for p in c["binding_pairs"]]  # a link's three shapes (a capsule) counted once
    assert len(set(links)) == len(links)


def _elbows_clear_of_the_wall(mech, step):
    """By hand, on the plot's grid at `step`: per elbow (2, N), whether the point is reached with
    that elbow and both the point and the elbow lie at x < WALL - R; and the points (N,) farther
    than 1e-9 m from every edge of those sets (where the grid's rounding cannot decide)."""
    lo, hi = mech.bounding_box("all")
    axes = [np.arange(lo[k], hi[k] + step / 2, step) for k in range(2)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 2)
    rho, phi = np.hypot(pts[:, 0], pts[:, 1]), np.arctan2(pts[:, 1], pts[:, 0])
    inside = (rho > L1 - L2) & (rho < L1 + L2)
    gamma = np.arccos(np.clip((L1 * L1 + rho * rho - L2 * L2) / (2 * L1 * np.maximum(rho, 1e-12)), -1, 1))
    c = WALL - R
    elbow_x = L1 * np.cos(np.stack([phi - gamma, phi + gamma]))
    elbows = inside & (pts[:, 0] < c) & (elbow_x < c)
    near = np.minimum.reduce([np.abs(pts[:, 0] - c), np.abs(elbow_x - c).min(axis=0), np.abs(rho - (L1 - L2)),
                              np.abs(rho - (L1 + L2))])
    return elbows.astype(int), near > 1e-9


def test_plot_counts_the_collision_free_elbows_by_hand(arm, tmp_path, capsys):  # noqa: F811
    # workspace-volume --plot with obstacles: the figure's map counts, per grid point, the elbows
    # whose arm clears the wall (P and that elbow at x < WALL - R, as above)
    from kinematics.analyses.collisions import margin_builder
    from kinematics.views import plots

    obstacles = _obstacles(tmp_path, HALF)
    cm = collision_model_of(arm, obstacles, self_collisions=False)
    mech = mechanism_of(arm)
    step = 0.023
    plots.headless()
    fig = plots.spatial_workspace(mech, "all", 2 * step, branch_margin=margin_builder(mech, arm, cm)(mech.branches),
                                  what="collision-free")
    drawn = np.ma.filled(fig.axes[0].collections[0].get_array(), 0).ravel()
    elbows, ok = _elbows_clear_of_the_wall(mech, step)
    want = elbows.sum(axis=0)
    assert ok.mean() > 0.99 and (want[ok] == 1).any() and (want[ok] == 2).any()
    assert np.array_equal(drawn[ok], want[ok])
    code, _, err = run_json(capsys, "workspace-volume", str(tmp_path / "arm2r.urdf"), "--obstacles",
                            str(tmp_path / "wall.yaml"), "--rtol", "1e-2", "--plot", str(tmp_path / "w.png"))
    assert code == 0 and (tmp_path / "w.png").stat().st_size > 10_000, err


def test_plot_with_chosen_branches_counts_only_those(arm, tmp_path):  # noqa: F811
    # --plot with --modes: each elbow's map on its own is one of the two by-hand elbow maps of the
    # test above, and the two add up to the map of both
    from kinematics.analyses.collisions import margin_builder
    from kinematics.views import plots

    cm = collision_model_of(arm, _obstacles(tmp_path, HALF), self_collisions=False)
    mech = mechanism_of(arm)
    step = 0.023
    plots.headless()
    margin = margin_builder(mech, arm, cm)(mech.branches)
    elbows, ok = _elbows_clear_of_the_wall(mech, step)
    maps = []
    for b in mech.branches:
        fig = plots.spatial_workspace(mech, "all", 2 * step, branch_margin=margin, what="collision-free", branches=[b])
        maps.append(np.ma.filled(fig.axes[0].collections[0].get_array(), 0).ravel())
        assert b in fig.axes[1].get_ylabel()  # the colour bar says which branch it counts
        assert any(np.array_equal(maps[-1][ok], e[ok].astype(int)) for e in elbows)
    assert not np.array_equal(maps[0][ok], maps[1][ok])
    assert np.array_equal((maps[0] + maps[1])[ok], elbows.sum(axis=0)[ok])
