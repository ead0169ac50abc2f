"""Collisions in Meshcat views (issue 30 item 5): `show --workspace --obstacles/--collisions`
draws the workspace points where every branch collides, grouped by the pair that binds there, and
the obstacles; headless, through the recorded scene."""

from __future__ import annotations

import re

import numpy as np

from kinematics.analyses.collisions import collision_model_of
from kinematics.generic.obstacles import load_obstacles
from kinematics.mechanisms import mechanism_of
from kinematics.model.robot import load_robot
from kinematics.views import meshcat as viz
from kinematics.views.meshcat.collision_views import add_obstacles

from .test_cli import run

FLOOR = "obstacles:\n  - {name: floor, halfspace: [0, 0, 1, -0.62]}\n"


def test_points_below_a_floor_are_drawn_apart_with_their_binding_pair(tmp_path):
    """p2us-results above a floor z >= -0.62 m, its workspace on a 0.03 m grid: the points drawn
    as colliding are exactly the grid points inside the kinematic workspace whose platform sphere
    (radius d + 0.02 m) crosses the floor (z < -0.572 m), all bound by the pair platform - floor;
    the floor is drawn; the rest is the collision-free workspace."""
    (tmp_path / "floor.yaml").write_text(FLOOR)
    robot = load_robot("p2us-results")
    mech = mechanism_of(robot)
    cm = collision_model_of(robot, load_obstacles(tmp_path / "floor.yaml"), self_collisions=False)
    step = 0.03
    scene = viz.parallel_view(robot, workspace=True, step=step, collisions=cm)
    tree = scene._window.tree["meshcat"]
    assert list(tree["overlays"]["colliding"]) == ["platform--floor"]
    assert list(tree["obstacles"]) == ["floor"]
    lo, hi = mech.bounding_box("all")
    axes = [np.arange(lo[k] + step / 2, hi[k], step) for k in range(3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    inside = (mech.margin(None, "all")(pts)[:, :-1] >= 0).any(axis=1)
    below = inside & (pts[:, 2] - (mech.params.d + 0.02) < -0.62)
    labels = [label for label, _ in scene.legend]
    drawn = [int(m.group(1)) for m in (re.search(r"colliding: platform - floor binds \((\d+) points\)", x)
                                       for x in labels) if m]
    assert drawn == [int(below.sum())] and 0 < below.sum() < inside.sum()
    assert any("collision-free" in x for x in labels) and "obstacle floor" in labels


def test_every_obstacle_shape_is_drawn(tmp_path, p2us):
    """Box, sphere, capsule, cylinder, half-space and mesh obstacles each become one mesh."""
    import trimesh

    trimesh.creation.box(extents=(0.1, 0.1, 0.1)).export(tmp_path / "part.stl")
    (tmp_path / "all.yaml").write_text("""obstacles:
  - {name: a, box: [0.1, 0.2, 0.3], xyz: [0.5, 0, 0]}
  - {name: b, sphere: 0.1, xyz: [-0.5, 0, 0]}
  - {name: c, capsule: [0.05, 0.3], xyz: [0, 0.5, 0]}
  - {name: d, cylinder: [0.05, 0.3], xyz: [0, -0.5, 0]}
  - {name: e, halfspace: [0, 0, 1, -1.0]}
  - {name: f, mesh: part.stl, xyz: [0.5, 0.5, 0]}
""")
    cm = collision_model_of(p2us, load_obstacles(tmp_path / "all.yaml"), self_collisions=False)
    scene = viz.Scene()
    assert add_obstacles(scene, cm) == 6 and scene.warnings == []
    assert sorted(scene._window.tree["meshcat"]["obstacles"]) == list("abcdef")


def test_show_workspace_with_obstacles_and_refusals(capsys, tmp_path):
    (tmp_path / "floor.yaml").write_text(FLOOR)
    out = tmp_path / "scene.html"
    code, _, err = run(capsys, "show", "p2us-results", "--workspace", "--step", "0.05", "--obstacles",
                       str(tmp_path / "floor.yaml"), "--export", str(out))
    assert code == 0, err
    page = out.read_text()
    assert "obstacle floor" in page and "colliding: platform - floor binds" in page
    for argv, needle in [(["show", "ur5", "--workspace", "--collisions", "--step", "0.005"], "too fine a step"),
                         (["show", "p2us", "--collisions"], "drawn with --workspace")]:
        code, _, err = run(capsys, *argv, "--export", str(tmp_path / "x.html"))
        assert code == 2 and needle in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x.html").exists()
