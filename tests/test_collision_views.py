"""Collisions in Meshcat views (issue 30 item 5): `show --workspace --obstacles/--collisions`
draws the workspace points where every branch collides, grouped by the pair that binds there, and
the obstacles; headless, through the recorded scene."""

from __future__ import annotations

import re

import numpy as np

from kinematics.analyses.collisions import collision_map, collision_model_of
from kinematics.generic.obstacles import load_obstacles
from kinematics.mechanisms import mechanism_of
from kinematics.model.robot import load_robot
from kinematics.views import meshcat as viz
from kinematics.views.meshcat.collision_views import add_obstacles

from .test_cli import run, run_json

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
    # the counts the CLI reports (`Scene.collision_counts`), by hand as above
    c = scene.collision_counts
    assert (c.mode, c.step, c.grid_points, c.reached) == ("spatial", step, len(pts), int(inside.sum()))
    assert c.free == int((inside & ~below).sum()) and c.binding_pairs == ((("platform", "floor"), int(below.sum())),)


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


def test_show_reports_the_counts_of_a_closed_loops_collision_grid(capsys, tmp_path):
    """`show p2us-results --workspace --collisions --json` on a 0.05 m grid: the collisions block's
    counts add up (free + colliding = reached, the binding pairs' points = colliding) and equal
    `collision_map` called here on the same grid (the cell centres inside the kinematic
    workspace; colliding where the margin is <= 0 with a pair binding), pair by pair of links; the
    human output prints the same counts."""
    step = 0.05
    out = tmp_path / "scene.html"
    code, d, err = run_json(capsys, "show", "p2us-results", "--workspace", "--collisions", "--step", str(step),
                            "--export", str(out))
    assert code == 0, err
    c = d["collisions"]
    assert c["mode"] == "spatial" and c["step_m"] == step and c["pairs_checked"] > 0
    assert c["free"] + c["colliding"] == c["reached"] and sum(p["points"] for p in c["binding_pairs"]) == c["colliding"]
    robot = load_robot("p2us-results")
    mech = mechanism_of(robot)
    cm = collision_model_of(robot, None, self_collisions=True)
    lo, hi = mech.bounding_box("all")
    axes = [np.arange(lo[k] + step / 2, hi[k], step) for k in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    pts = grid[(mech.margin(None, "all")(grid)[:, :-1] >= 0).any(axis=1)]
    margin, pair = collision_map(mech, robot, cm, pts)
    hit = (margin <= 0) & (pair >= 0)
    assert (c["grid_points"], c["reached"], c["colliding"]) == (len(grid), len(pts), int(hit.sum()))
    assert 0 < c["colliding"] < c["reached"]
    by_links: dict[tuple[str, str], int] = {}
    for k in pair[hit]:
        by_links[cm.pair_links[k]] = by_links.get(cm.pair_links[k], 0) + 1
    assert len(c["binding_pairs"]) == len(by_links)  # a pair of links with several shapes counted once
    assert {tuple(p["links"]): p["points"] for p in c["binding_pairs"]} == by_links
    assert [p["points"] for p in c["binding_pairs"]] == sorted(by_links.values(), reverse=True)
    code, text, err = run(capsys, "show", "p2us-results", "--workspace", "--collisions", "--step", str(step),
                          "--export", str(out))
    assert code == 0, err
    for label, n in [("in the kinematic workspace", c["reached"]), ("collision-free", c["free"]),
                     ("colliding", c["colliding"]), ("grid points", c["grid_points"])]:
        assert re.search(rf"^{label} +: {n:,}", text, flags=re.M), (label, text)


def test_binding_pairs_count_a_pair_of_links_once_whatever_its_shapes():
    """`binding_pairs` by hand: shapes 0 and 2 are both a - b (a link with two shapes), 1 is a - c;
    points 0-3 collide (pairs 0, 2, 2, 1), point 4 does not (its pair ignored): a - b binds at 3
    points, a - c at 1, most first."""
    from types import SimpleNamespace

    from kinematics.analyses.collisions import binding_pairs

    model = SimpleNamespace(pair_links=[("a", "b"), ("a", "c"), ("a", "b")])
    pair = np.array([0, 2, 2, 1, 1])
    colliding = np.array([True, True, True, True, False])
    assert binding_pairs(model, pair, colliding) == [(("a", "b"), 3), (("a", "c"), 1)]
