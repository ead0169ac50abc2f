"""Collision-free workspaces (kinematics.analyses.collisions): an area derived by hand, and
p2us-results' sliver above the base, which the rods reach only through the base plate."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinematics.analyses.collision_volume import measure_collision_workspace
from kinematics.analyses.collisions import collision_model_of
from kinematics.generic.capsules import AnalyticDistances
from kinematics.generic.collision import CollisionModel
from kinematics.mechanisms import mechanism_of
from kinematics.model.robot import load_robot

WALL = """<robot name="wall2r">
  <link name="base">
    <collision><origin xyz="0.6 0 0"/><geometry><box size="0.2 4 1"/></geometry></collision>
  </link>
  <link name="link1"/>
  <link name="link2"/>
  <link name="tool"><collision><origin xyz="0 0 0"/><geometry><sphere radius="0.05"/></geometry></collision></link>
  <joint name="joint1" type="revolute"><parent link="base"/><child link="link1"/><axis xyz="0 0 1"/>
    <limit lower="-3.141592653589793" upper="3.141592653589793" effort="1" velocity="1"/></joint>
  <joint name="joint2" type="revolute"><parent link="link1"/><child link="link2"/><origin xyz="0.4 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-3.141592653589793" upper="3.141592653589793" effort="1" velocity="1"/></joint>
  <joint name="tool_joint" type="fixed"><parent link="link2"/><child link="tool"/><origin xyz="0.3 0 0"/></joint>
</robot>"""


def _disk_left_of(R: float, c: float) -> float:
    """Area of the disk of radius R about the origin where x <= c (-R <= c <= R)."""
    return R * R * (math.pi - math.acos(c / R)) + c * math.sqrt(R * R - c * c)


def test_planar_arm_beside_a_wall_loses_the_area_past_it(tmp_path):
    """A 2R arm (0.4 + 0.3 m, both joints +/-180 deg: each elbow reaches the whole annulus
    0.1 <= r <= 0.7) whose tool carries a sphere of radius 0.05, beside a wall x >= 0.5 (a box
    0.2 m thick on the base). The tool is free where x <= 0.45: the area is the annulus's part left
    of x = 0.45, A(0.7, 0.45) - pi 0.1^2 with A(R, c) = R^2 (pi - acos(c/R)) + c sqrt(R^2 - c^2),
    and the wall removes the rest, all of it through the one pair (base, tool)."""
    (tmp_path / "wall2r.urdf").write_text(WALL)
    robot = load_robot(tmp_path / "wall2r.urdf")
    mech = mechanism_of(robot)
    assert mech.family == "scara"
    cm = CollisionModel.from_robot(robot, exclude_touching=False)  # the reference pose is in the wall
    cw = measure_collision_workspace(mech, robot, step=0.005, rtol=1e-4, collision_model=cm)
    free = _disk_left_of(0.7, 0.45) - math.pi * 0.01
    annulus = math.pi * (0.49 - 0.01)
    ws = cw.workspace
    # rtol 1e-4 on the error estimates; the sampled columns' root brackets are 1e-12 m
    assert ws.total == pytest.approx(free, rel=3e-4) and abs(ws.total - free) <= 3 * ws.error + 1e-9
    assert cw.kinematic == pytest.approx(annulus, rel=3e-4)
    assert [p.links for p in cw.pairs] == [("base", "tool")]
    assert cw.pairs[0].removed == pytest.approx(annulus - free, rel=2e-3)
    for k in range(2):  # each elbow alone reaches the same free area
        assert ws.result.estimate[k] == pytest.approx(free, rel=3e-4)


def test_p2us_results_loses_the_sliver_above_the_base():
    """Above the base frame (z >= 0) p2us-results reaches a sliver (docs/paper-b-reproduction.md:
    47 cm^3 at 1 cm voxels, z 0.09..0.13 m) only with the rods through the base plate: with
    collisions nothing is left there, and each rod-plate pair alone removes all of it."""
    robot = load_robot("p2us-results")
    mech = mechanism_of(robot)
    lo, hi = mech.bounding_box("all")
    cw = measure_collision_workspace(mech, robot, step=0.01, rtol=1e-2, branches=["---"], check=False,
                                     box=(np.array([lo[0], lo[1], 0.0]), hi), max_points=3_000_000)
    assert cw.kinematic == pytest.approx(47e-6, rel=0.05)
    assert cw.workspace.total == 0.0 and cw.removed == cw.kinematic
    rods = {("base", f"rod_{i}_{k}") for i in (1, 2, 3) for k in (1, 2)}
    assert {p.links for p in cw.pairs} == rods
    for p in cw.pairs:  # the sliver is the one place any of them binds: each removes all of it
        assert p.removed == pytest.approx(cw.removed, abs=p.error)


FLOOR = "obstacles:\n  - {name: floor, halfspace: [0, 0, 1, -0.62]}\n"


def test_volume_above_a_floor_is_the_kinematic_volume_above_the_platforms_reach(tmp_path):
    """p2us-results (mode ---) above a floor z >= -0.62 m, in the slab of the workspace 0.04 m
    either side of z0 = -0.62 + 0.048: its lowest body is the platform's sphere (radius
    d + 0.02 = 0.048 m about the task point, the generator's documented sizes), so the
    collision-free volume is the kinematic volume of the slab's upper half, measured independently
    by the exact columns over that box, and the floor pair removes the lower half. The pre-scan
    clears the cells far above the floor; distances are evaluated only in the others."""
    from kinematics.analyses.columns import column_volume
    from kinematics.generic.obstacles import load_obstacles

    (tmp_path / "floor.yaml").write_text(FLOOR)
    robot = load_robot("p2us-results")
    mech = mechanism_of(robot)
    lo, hi = mech.bounding_box("all")
    z0 = -0.62 + mech.params.d + 0.02
    cw = measure_collision_workspace(mech, robot, step=0.04, rtol=2e-2, branches=["---"], check=False,
                                     obstacles=load_obstacles(tmp_path / "floor.yaml"), self_collisions=False,
                                     box=(np.array([lo[0], lo[1], z0 - 0.04]), np.array([hi[0], hi[1], z0 + 0.04])))
    upper = column_volume(mech.margin(["---"]), np.array([lo[0], lo[1], z0]), np.array([hi[0], hi[1], z0 + 0.04]),
                          step=0.04, rtol=1e-5)
    free, err = cw.workspace.total, cw.workspace.error
    assert cw.kinematic - upper.estimate[-1] > 0.3 * cw.kinematic  # the floor removes a good part
    # both within their error estimates (rtol 2e-2 and 1e-5)
    assert abs(free - upper.estimate[-1]) <= err + upper.error[-1] and err <= 2e-2 * free
    assert cw.pairs[0].links == ("platform", "floor")  # the lowest body: most points below the floor
    assert cw.pairs[0].removed == pytest.approx(cw.kinematic - upper.estimate[-1], abs=cw.pairs[0].error + err)


def test_cli_reports_the_binding_pair_and_its_removal(tmp_path, capsys):
    """`workspace-volume --collisions --json` on the wall arm: the area, the kinematic area and
    the one binding pair with what it removes (the hand-derived figures, to 1 %)."""
    from .test_cli import run_json

    (tmp_path / "wall2r.urdf").write_text(WALL)
    side = tmp_path / "wall2r.loops.yaml"
    assert not side.exists()
    code, d, _ = run_json(capsys, "workspace-volume", str(tmp_path / "wall2r.urdf"), "--collisions", "--step", "0.01",
                          "--rtol", "1e-2")
    assert code == 0
    free = _disk_left_of(0.7, 0.45) - math.pi * 0.01
    c = d["collisions"]
    # the neutral pose (arm stretched along x) is in the wall: the pair is left out as touching
    assert d["area_m2"] == pytest.approx(math.pi * 0.48, rel=1e-2) and c["removed"] == pytest.approx(0, abs=1e-6)
    assert [e["reason"] for e in c["excluded"]] == ["touching"] and c["binding_pairs"] == []
    assert free < d["area_m2"]


def test_delta_pairs_never_near_contact_give_the_kinematic_volume(rng):
    """No pair of the Delta comes near contact inside its workspace (mode ---): the pre-scan
    clears every cell and the collision-free volume is the kinematic one from its exact columns,
    no pair binding. Held independently by coal: at random points of the workspace (rejection
    sampling in its box), the configurations built by `joint_values` have every pair apart."""
    from kinematics.analyses.collisions import collision_model_of
    from kinematics.analyses.workspace import measure_workspace

    robot = load_robot("delta")
    mech = mechanism_of(robot)
    cw = measure_collision_workspace(mech, robot, step=0.04, rtol=1e-2, branches=["---"], check=False)
    kin = measure_workspace(mech, step=0.04, rtol=1e-2, branches=["---"])
    assert cw.pairs == () and cw.collision["pairs_that_can_bind"] == 0
    assert cw.workspace.total == pytest.approx(kin.total, rel=1e-12) and cw.removed == 0.0
    lo, hi = mech.bounding_box("all")
    pts = lo + (hi - lo) * rng.random((400, 3))
    pts = pts[mech.margin(["---"])(pts)[:, 0] > 0][:60]
    assert len(pts) >= 30
    cm = collision_model_of(robot)
    q = np.array([robot.configuration([mech.joint_values(p, "---")[n] for n in robot.joint_names]) for p in pts])
    assert cm.distances(q).min() > 0


def test_a_generic_closed_loop_is_collision_aware_as_the_closed_forms():
    """p2us-results through the generic closed-loop solver (no closed forms): its collision-aware
    union is free exactly where the closed forms' is, at 3000 random points of the box (both paths
    place the same URDF's shapes, one from the batched solver's joint values, one from the IK
    closed forms), away from contact (|margin| > 1e-6 m, far above both solvers' ~1e-10 m). (The
    two label their working modes differently, so only the union is compared.)"""
    from kinematics.analyses.collisions import CollisionMargin
    from kinematics.mechanisms.closed_loop.mechanism import GenericClosedLoop

    robot = load_robot("p2us-results")
    closed, generic = mechanism_of(robot), GenericClosedLoop(robot)
    cm = collision_model_of(robot)
    dist = AnalyticDistances(cm)
    lo, hi = closed.bounding_box("all")
    p = lo + (hi - lo) * np.random.default_rng(5).random((3000, 3))
    mc = CollisionMargin(closed, robot, dist, closed.branches, "all")(p)[:, -1]
    mg = CollisionMargin(generic, robot, dist, generic.branches, "all")(p)[:, -1]
    sure = np.abs(mc) > 1e-6
    assert (mc[sure] > 0).sum() > 100 and (mc[sure] <= 0).sum() > 100  # both kinds exercised
    assert np.array_equal(mc[sure] > 0, mg[sure] > 0)
