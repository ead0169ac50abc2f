"""Collision-aware workspaces of serial arms (kinematics.analyses.serial_collisions, issue 30):
the reach search's configurations joined to the pair distances, held to areas and volumes derived
by hand or integrated independently of the code under test.

Models: a planar 2R arm of capsules beside a wall (test_collision_obstacles' arm and area by hand,
measured here as a generic serial arm, not by the planar arm's closed forms), and a spatial 3R
arm -- a full-turn yaw at the origin carrying a 2R arm in a vertical plane (shoulder on the yaw
axis, links L1 = 0.4 m and L2 = 0.3 m, capsules of radius R = 0.02 m) -- beside the same wall
(spatial: the wall changes with the base's turn) or with a post on its turret (revolved: the post
turns with the arm).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinematics.analyses.collision_volume import measure_collision_workspace
from kinematics.analyses.collisions import collision_model_of
from kinematics.analyses.serial_collisions import SerialCollisionMargin, collision_reach, turn_invariant
from kinematics.errors import KinematicsWarning
from kinematics.generic.capsules import AnalyticDistances
from kinematics.generic.obstacles import load_obstacles
from kinematics.mechanisms import mechanism_of
from kinematics.mechanisms.serial.mechanism import SerialArm
from kinematics.model.robot import load_robot

from .test_collision_obstacles import ARM, HALF, _free_areas

L1, L2, R, WALL = 0.4, 0.3, 0.02, 0.35
"""The 3R arm's link lengths, its capsules' radius and the wall's face x = WALL [m] (the solid x >= WALL)."""
DOWN = 0.05
"""The 4R arm's tool offset past its wrist [m] (`_arm4`)."""
RP, POST = 0.1, (-0.6, -0.05)
"""The turret's post: a capsule of radius RP [m] on the yaw axis between these heights [m]."""


def _capsule(a: tuple[float, float, float], b: tuple[float, float, float], r: float) -> str:
    """A capsule of radius r between a and b (on a coordinate axis) as URDF writes one: a cylinder
    and a sphere on each end face."""
    mid = " ".join(str((x + y) / 2) for x, y in zip(a, b, strict=True))
    length = math.dist(a, b)
    rpy = "0 1.5707963267948966 0" if a[0] != b[0] else "0 0 0"
    return (f'<collision><origin xyz="{mid}" rpy="{rpy}"/><geometry><cylinder radius="{r}" length="{length}"/>'
            f'</geometry></collision>' + "".join(f'<collision><origin xyz="{p[0]} {p[1]} {p[2]}"/><geometry>'
                                                 f'<sphere radius="{r}"/></geometry></collision>' for p in (a, b)))


def _arm3(post: bool) -> str:
    lim = f'<limit lower="{-math.pi}" upper="{math.pi}" effort="1" velocity="1"/>'
    turret = _capsule((0, 0, POST[0]), (0, 0, POST[1]), RP) if post else ""
    return f"""<robot name="arm3r_capsules">
  <link name="base"/><link name="turret">{turret}</link>
  <link name="link1">{_capsule((0, 0, 0), (L1, 0, 0), R)}</link>
  <link name="link2">{_capsule((0, 0, 0), (L2, 0, 0), R)}</link><link name="tool"/>
  <joint name="yaw" type="revolute"><parent link="base"/><child link="turret"/><axis xyz="0 0 1"/>{lim}</joint>
  <joint name="pitch" type="revolute"><parent link="turret"/><child link="link1"/><axis xyz="0 1 0"/>{lim}</joint>
  <joint name="elbow" type="revolute"><parent link="link1"/><child link="link2"/><origin xyz="{L1} 0 0"/>
    <axis xyz="0 1 0"/>{lim}</joint>
  <joint name="tool_joint" type="fixed"><parent link="link2"/><child link="tool"/><origin xyz="{L2} 0 0"/></joint>
</robot>"""


def _arm4(post: bool) -> str:
    """The 3R arm plus a full-turn wrist pitch at the tool point carrying a tool frame DOWN [m]
    along its z axis (no collision shape past link 2): with the tool's z axis held at -z the wrist
    pitch is pi - pitch - elbow, and the tool point is the 3R arm's shifted down by DOWN."""
    lim = f'<limit lower="{-math.pi}" upper="{math.pi}" effort="1" velocity="1"/>'
    return _arm3(post).replace('<link name="tool"/>', '<link name="hand"/><link name="tool"/>').replace(
        f'<joint name="tool_joint" type="fixed"><parent link="link2"/><child link="tool"/><origin xyz="{L2} 0 0"/>',
        f'<joint name="wrist" type="revolute"><parent link="link2"/><child link="hand"/><origin xyz="{L2} 0 0"/>'
        f'<axis xyz="0 1 0"/>{lim}</joint><joint name="tool_joint" type="fixed"><parent link="hand"/>'
        f'<child link="tool"/><origin xyz="0 0 {DOWN}"/>')


def _profile(h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Midpoints (rho, z) of an h-grid over the profile of the 3R arm's reachable shell
    L1 - L2 <= |p| <= L1 + L2, and its two elbows' in-plane directions (angles a -+ g from the
    u axis of the arm's plane, the law of cosines)."""
    rho, z = np.meshgrid(np.arange(h / 2, L1 + L2, h), np.arange(-(L1 + L2) + h / 2, L1 + L2, h), indexing="ij")
    rho, z = rho.ravel(), z.ravel()
    r = np.hypot(rho, z)
    keep = (r >= L1 - L2) & (r <= L1 + L2)
    rho, z, r = rho[keep], z[keep], r[keep]
    g = np.arccos(np.clip((L1 * L1 + r * r - L2 * L2) / (2 * L1 * r), -1.0, 1.0))
    a = np.arctan2(z, rho)
    return rho, z, a - g, a + g


def _wall_volume(h: float) -> float:
    """The 3R arm's volume clear of the wall [m^3], integrated on the profile.

    A capsule clears x >= WALL iff its segment's largest x is below c = WALL - R; link 1 starts on
    the axis (x = 0), so the arm is free iff the elbow E and the tool P have x < c. At the target
    (rho, phi, z) with the yaw at phi, the tool has x = rho s and the elbow x = u_E s (s = cos phi,
    u_E = L1 cos(angle) its in-plane coordinate); with the yaw at phi + pi the arm reaches in its
    plane's mirror, the elbows' x the same set (u_E -> -u_E, s -> -s). So per (rho, z) the free
    azimuths are {phi : rho s < c and (u_E1 s < c or u_E2 s < c)}, a union of intervals in s whose
    phi-measure is 2 (acos lo - acos hi) each; the volume is the integral of rho times that measure
    over the profile (midpoint rule; h = 1e-3 and 5e-4 differ by 2e-6 m^3)."""
    rho, _, e1, e2 = _profile(h)
    c = WALL - R
    ue = np.stack([L1 * np.cos(e1), L1 * np.cos(e2)], axis=1)
    with np.errstate(divide="ignore"):
        te = np.where(ue != 0, c / ue, np.inf)
    ends = np.sort(np.clip(np.column_stack([-np.ones_like(rho), np.ones_like(rho), c / rho, te]), -1, 1), axis=1)
    lo, hi = ends[:, :-1], ends[:, 1:]
    s = 0.5 * (lo + hi)
    elbow = np.zeros(s.shape, dtype=bool)
    for k in range(2):
        u, t = ue[:, k:k + 1], te[:, k:k + 1]
        elbow |= np.where(u > 0, s < t, np.where(u < 0, s > t, True))
    free = (s < (c / rho)[:, None]) & elbow
    return float((rho * (2 * (np.arccos(lo) - np.arccos(hi)) * free).sum(axis=1)).sum() * h * h)


def _segment_distance(p1: np.ndarray, p2: np.ndarray, q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Distances between 2-D segments p1p2 and q1q2 (N, 2): 0 where they cross, else the smallest
    of the four end-to-segment distances."""
    def to_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        ab = b - a
        t = np.clip(((p - a) * ab).sum(-1) / (ab * ab).sum(-1), 0, 1)
        return np.linalg.norm(p - a - t[:, None] * ab, axis=-1)

    def side(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return (a[:, 0] - o[:, 0]) * (b[:, 1] - o[:, 1]) - (a[:, 1] - o[:, 1]) * (b[:, 0] - o[:, 0])

    d = np.minimum.reduce([to_segment(p1, q1, q2), to_segment(p2, q1, q2), to_segment(q1, p1, p2),
                           to_segment(q2, p1, p2)])
    cross = (side(p1, p2, q1) * side(p1, p2, q2) < 0) & (side(q1, q2, p1) * side(q1, q2, p2) < 0)
    return np.where(cross, 0.0, d)


def _post_clearance(rho: np.ndarray, z: np.ndarray, e1: np.ndarray, e2: np.ndarray) -> np.ndarray:
    """The better elbow's clearance [m] of link 2 from the turret's post at profile points
    (rho, z) with elbow angles e1, e2 (`_profile`): the post lies on the yaw axis, in the arm's
    plane, so the pair's distance is the plane's segment distance less R + RP, the same at every
    azimuth (the post turns with the arm)."""
    tool = np.stack([rho, z], axis=1)
    q1, q2 = np.tile([0.0, POST[0]], (len(rho), 1)), np.tile([0.0, POST[1]], (len(rho), 1))
    elbows = [L1 * np.stack([np.cos(e), np.sin(e)], axis=1) for e in (e1, e2)]
    return np.maximum(*(_segment_distance(elbow, tool, q1, q2) - (R + RP) for elbow in elbows))


def _post_volume(h: float) -> float:
    """The 3R arm's volume with link 2 clear of the turret's post [m^3]: per (rho, z) a free elbow
    (`_post_clearance`) frees the whole circle, 2 pi rho (midpoint rule; h = 1e-3 and 5e-4 differ
    by 1.3e-6 m^3)."""
    rho, z, e1, e2 = _profile(h)
    free = _post_clearance(rho, z, e1, e2) >= 0
    return float(2 * math.pi * (rho * free).sum() * h * h)


def _wall_clearance(p: np.ndarray) -> np.ndarray:
    """At world points p (N, 3): the 3R arm's clearance [m] from the wall by hand, the better
    elbow's (the tool and that elbow at x < WALL - R, `_wall_volume`'s condition at the point's
    azimuth), and the reach shell's (L1 - L2 <= |p| <= L1 + L2): > 0 where some configuration
    reaches p clear of the wall."""
    rho, r = np.hypot(p[:, 0], p[:, 1]), np.linalg.norm(p, axis=1)
    g = np.arccos(np.clip((L1 * L1 + r * r - L2 * L2) / (2 * L1 * np.maximum(r, 1e-12)), -1, 1))
    a, cos_phi = np.arctan2(p[:, 2], rho), p[:, 0] / np.maximum(rho, 1e-12)
    c = WALL - R
    elbow = np.maximum(c - L1 * np.cos(a - g) * cos_phi, c - L1 * np.cos(a + g) * cos_phi)
    return np.minimum(np.minimum(c - p[:, 0], elbow), np.minimum(r - (L1 - L2), L1 + L2 - r))


@pytest.fixture(scope="module")
def arm3(tmp_path_factory):
    folder = tmp_path_factory.mktemp("arm3")
    (folder / "arm3.urdf").write_text(_arm3(False))
    (folder / "arm3p.urdf").write_text(_arm3(True))
    (folder / "wall.yaml").write_text(f"obstacles:\n  - {{name: wall, halfspace: [-1, 0, 0, {-WALL}]}}\n")
    return folder


def test_planar_arm_as_a_serial_arm_beside_a_wall(tmp_path):
    """The planar 2R arm measured by the reach search (a `SerialArm`, not the planar arm's closed
    forms): its free area is the union's by hand (both elbows: the search's configurations)."""
    (tmp_path / "arm.urdf").write_text(ARM)
    (tmp_path / "wall.yaml").write_text(HALF)
    robot = load_robot(tmp_path / "arm.urdf")
    cw = measure_collision_workspace(SerialArm(robot), robot, step=0.02, rtol=3e-3,
                                     obstacles=load_obstacles(tmp_path / "wall.yaml"), self_collisions=False)
    area = _free_areas()[1]
    assert cw.workspace.result.converged
    assert abs(cw.workspace.total - area) <= cw.workspace.error
    assert abs(cw.kinematic - math.pi * (0.7**2 - 0.1**2)) <= cw.kinematic_error
    assert cw.collision["search"]["mode"] == "planar"


@pytest.fixture
def arm_margin(tmp_path):
    """The 2R arm beside the wall (x >= 0.35 m): its collision-aware margin (the wall pairs only)."""
    (tmp_path / "arm.urdf").write_text(ARM)
    (tmp_path / "wall.yaml").write_text(HALF)
    robot = load_robot(tmp_path / "arm.urdf")
    mech = SerialArm(robot)
    dist = AnalyticDistances(collision_model_of(robot, load_obstacles(tmp_path / "wall.yaml"), False))
    return SerialCollisionMargin(mech, robot, dist, collision_reach(mech, robot, dist))


def test_margin_takes_the_best_configuration(arm_margin, rng):
    """At random points of the 2R arm's annulus the margin's sign is that of the better elbow's
    clearance by hand (elbow and tool x below WALL - R for a free elbow), away from zero."""
    margin = arm_margin
    rho = np.sqrt(rng.uniform(0.11**2, 0.69**2, 400))
    phi = rng.uniform(-math.pi, math.pi, 400)
    pts = np.stack([rho * np.cos(phi), rho * np.sin(phi)], axis=1)
    g = np.arccos((0.4**2 + rho**2 - 0.3**2) / (2 * 0.4 * rho))
    c = 0.35 - 0.02
    elbows = np.stack([0.4 * np.cos(phi - g), 0.4 * np.cos(phi + g)], axis=1)
    clear = np.minimum(c - pts[:, :1], c - elbows).max(axis=1)  # the better elbow's clearance [m]
    m = margin(pts)[:, -1]
    sure = np.abs(clear) > 1e-6
    one_free = sure & (np.minimum(c - pts[:, :1], c - elbows).min(axis=1) < 0) & (clear > 0)
    assert one_free.sum() > 20  # points where one elbow collides and the other is free
    assert np.array_equal(m[sure] > 0, clear[sure] > 0)


def test_restarts_evaluate_each_distinct_configuration_once(arm_margin, rng, monkeypatch):
    """The 2R arm beside the wall (non-redundant: two elbows reach each point). `distinct_distances`
    evaluates three configurations repeated 8 times each (1e-10 rad apart, within one 1e-8 rad
    rounding cell) in one call of 3 rows, each row the distances of its own configuration; where the
    first solution collides, the restarts' 24 descents end at the two elbows, so the margin's
    distance calls take over 5x fewer configurations than with every descent evaluated, and the
    margin is the same to 1e-8 m (merged configurations within 1e-8 rad, reach 0.7 m)."""
    import kinematics.analyses.serial_collisions as sc

    margin = arm_margin
    dist = margin.distances
    rows: list[int] = []
    evaluate = dist.distances

    def counted(q: np.ndarray, signs: bool = False) -> np.ndarray:
        rows.append(len(q))
        return evaluate(q, signs=signs)

    monkeypatch.setattr(dist, "distances", counted)
    configs = np.array([[0.3, 1.2], [-0.7, 0.4], [1.1, -2.0]])
    Q = np.repeat(configs, 8, axis=0) + rng.uniform(-1e-10, 1e-10, (24, 2))
    D = margin.distinct_distances(Q)
    assert rows == [3]
    own = evaluate(margin.full_configurations(Q), signs=True)
    assert np.max(np.abs(D - own)) <= 1e-8  # each row its own configuration's, to its 1e-10 rad offset

    rho = np.sqrt(rng.uniform(0.11**2, 0.69**2, 400))
    phi = rng.uniform(-math.pi, math.pi, 400)
    pts = np.stack([rho * np.cos(phi), rho * np.sin(phi)], axis=1)
    rows.clear()
    k, best, _, _, _ = margin.evaluate(pts)
    merged = sum(rows[1:])  # the restarts' calls (the first: one solution per point)
    monkeypatch.setattr(sc, "SAME_CONFIGURATION", 1e-300)  # only bit-identical rows merge
    rows.clear()
    k2, best2, _, _, _ = margin.evaluate(pts)
    assert merged > 0 and sum(rows[1:]) > 5 * merged
    assert np.array_equal(k, k2) and np.max(np.abs(best - best2)) <= 1e-8


def test_spatial_arm_beside_a_wall_is_measured_in_3d(arm3):
    """The 3R arm beside the wall: the wall pairs change with the yaw, so the search runs in 3-D;
    the volume is the profile integral by hand (to 3e-6 m^3) within its error estimate."""
    robot = load_robot(arm3 / "arm3.urdf")
    mech = mechanism_of(robot)
    assert mech.reach.setup.mode == "revolved"  # kinematically a solid of revolution
    cw = measure_collision_workspace(mech, robot, step=0.08, rtol=1e-2,
                                     obstacles=load_obstacles(arm3 / "wall.yaml"), self_collisions=False)
    assert cw.collision["search"]["mode"] == "spatial"
    assert cw.workspace.result.converged
    assert abs(cw.workspace.total - _wall_volume(1e-3)) <= cw.workspace.error + 3e-6
    assert abs(cw.kinematic - 4 / 3 * math.pi * (0.7**3 - 0.1**3)) <= cw.kinematic_error
    assert {p.links for p in cw.pairs} == {("link1", "wall"), ("link2", "wall")}


def test_spatial_collision_search_stops_on_its_budget(arm3, monkeypatch):
    """A collision-aware 3-D measure ends on its search budget (an evaluation there costs a search
    and every pair's distances): not converged, the budget named, its error covering the volume by
    hand. 20,000 evaluations: under the starting grid's and one refinement round's need at 0.04 m
    and rtol 1e-3, so the run must stop on it."""
    import kinematics.analyses.serial_collisions as sc

    monkeypatch.setattr(sc, "SEARCHES", 20_000)
    robot = load_robot(arm3 / "arm3.urdf")
    with pytest.warns(KinematicsWarning, match="will likely stop on its search budget"):  # said at the start
        cw = measure_collision_workspace(mechanism_of(robot), robot, step=0.04, rtol=1e-3,
                                         obstacles=load_obstacles(arm3 / "wall.yaml"), self_collisions=False)
    r = cw.workspace.result
    assert not r.converged and r.out_of_budget is not None and bool(r.out_of_budget[-1])
    assert r.points_evaluated <= 3 * 20_000  # the budget, a round begun and the pre-scan's grid
    assert abs(cw.workspace.total - _wall_volume(1e-3)) <= cw.workspace.error + 3e-6


def test_revolved_arm_with_a_post_keeps_its_profile(arm3):
    """The 3R arm with a post on its turret: the only pair turns with the yaw, so the measure stays
    on the profile (Pappus); the volume is the profile integral by hand within its error estimate."""
    robot = load_robot(arm3 / "arm3p.urdf")
    mech = mechanism_of(robot)
    dist = AnalyticDistances(collision_model_of(robot))
    assert turn_invariant(robot, dist, mech.reach)
    cw = measure_collision_workspace(mech, robot, step=0.05, rtol=1e-3)
    assert cw.collision["search"]["mode"] == "revolved"
    assert cw.workspace.result.converged
    assert abs(cw.workspace.total - _post_volume(1e-3)) <= cw.workspace.error + 2e-6
    assert cw.kinematic - cw.workspace.total > 0.02  # the post removes 0.029 m^3
    walled = AnalyticDistances(collision_model_of(robot, load_obstacles(arm3 / "wall.yaml")))
    assert not turn_invariant(robot, walled, mech.reach)


def test_tool_pointing_down_with_a_post_is_the_3r_volume(arm3, capsys):
    """`workspace-volume --collisions --tool-axis 0 0 -1` of the 4R arm with the post: every tool
    point is the 3R arm's wrist shifted down by DOWN at the same configuration of its links (the
    wrist carries no shape), so the collision-free volume is the 3R arm's with the post by hand
    (`_post_volume`), the kinematic one the shell's; measured on the profile (the held axis and the
    pair both turn with the base)."""
    from .test_cli import run_json

    (arm3 / "arm4p.urdf").write_text(_arm4(True))
    code, d, err = run_json(capsys, "workspace-volume", str(arm3 / "arm4p.urdf"), "--collisions", "--tool-axis",
                            "0", "0", "-1", "--step", "0.06", "--rtol", "2e-3")
    assert code == 0, err
    assert d["parameters"]["orientation"]["tool_z"] == [0.0, 0.0, -1.0] and d["converged"]
    assert d["collisions"]["search"]["mode"] == "revolved"
    assert abs(d["volume_m3"] - _post_volume(1e-3)) <= d["error_estimate"] + 2e-6
    c = d["collisions"]
    assert abs(c["kinematic_volume"] - 4 / 3 * math.pi * (0.7**3 - 0.1**3)) <= c["kinematic_error_estimate"]


def test_cli_serial_arm_with_obstacles(arm3, capsys):
    """`workspace-volume` of a serial arm with --obstacles answers (JSON: the search's mode, the
    binding pairs); its --points are the grid points the 3R arm reaches clear of the wall by hand
    (the tool and one elbow at x < WALL - R, `_wall_volume`'s condition at each point's azimuth),
    those within 1 mm of a boundary aside."""
    from .test_cli import run_json

    urdf, wall, listed = str(arm3 / "arm3.urdf"), str(arm3 / "wall.yaml"), arm3 / "free.npy"
    code, d, _ = run_json(capsys, "workspace-volume", urdf, "--obstacles", wall, "--step", "0.1", "--rtol", "5e-2",
                          "--points", str(listed))
    assert code == 0
    assert d["collisions"]["search"]["mode"] == "spatial" and d["collisions"]["obstacles"] == ["wall"]
    assert d["volume_m3"] < d["collisions"]["kinematic_volume"]
    axis = np.arange(-0.65, 0.7, 0.1)  # cell centres of the reach ball's box at the step
    p = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    clear = _wall_clearance(p)
    sure = np.abs(clear) > 1e-3
    got = {tuple(np.round(x, 6)) for x in np.load(listed)}
    expected = {tuple(np.round(x, 6)) for x in p[sure & (clear > 0)]}
    unsure = {tuple(np.round(x, 6)) for x in p[~sure]}
    assert got - unsure == expected and len(expected) > 500


def test_ur5_self_collisions_through_coal(ur5):
    """ur5 (meshes, example-robot-data): its base link's pairs change with the base's turn, so the
    search runs in 3-D. On a grid about its base, by coal's own distances
    (`CollisionModel.distances`, not the closed forms): where the margin says free, its
    configuration reaches the point with every pair apart; where it says colliding, every
    configuration the search found (its solution and the first 4 x restarts seeds' descents)
    collides; both kinds occur (the tool inside the base and shoulder)."""
    from kinematics.analyses.serial_collisions import ESCALATE

    mech = mechanism_of(ur5)
    model = collision_model_of(ur5)
    dist = AnalyticDistances(model)
    reach = collision_reach(mech, ur5, dist)
    assert reach.setup.mode == "spatial" and not turn_invariant(ur5, dist, mech.reach)
    margin = SerialCollisionMargin(mech, ur5, dist, reach)
    g = np.linspace(-0.15, 0.15, 5)
    pts = np.stack(np.meshgrid(g, g, np.linspace(0.0, 0.3, 4), indexing="ij"), axis=-1).reshape(-1, 3)
    k, _, _, _, q = margin.evaluate(pts)
    m = margin(pts)[:, -1]
    inside = np.flatnonzero(k > 0)
    said_free = inside[m[inside] > 0]
    assert (np.abs(reach.chain_fk(q[said_free]) - pts[said_free]) <= 1e-9).all()  # REACH_TOL = 1e-10
    assert (model.distances(margin.full_configurations(q[said_free])).min(axis=1) > 0).all()
    q0 = reach.distance(pts)[1]  # the same batch as the margin's (its warm starts run along it)
    said = inside[m[inside] <= 0]
    Qs, ok = reach.solutions(pts[said], 0, ESCALATE * reach.restarts)
    for n, at in enumerate(said):
        Q = np.vstack([q0[at], Qs[n][ok[n]]])
        assert (model.distances(margin.full_configurations(Q)).min(axis=1) <= 0).all()
    assert 0 < len(said) < len(inside)


def test_ur5_null_space_steps_find_what_a_larger_search_finds(ur5):
    """Near its base (a 5 cm grid, 392 points) the ur5's default search with its null-space steps
    calls colliding exactly the points a search from 4 x the restarts (escalating to 96 seeds, its
    own steps too) does: 32; without the steps the default search missed 5 free ones (37)."""
    from kinematics.mechanisms.serial.reach import Reach

    mech = mechanism_of(ur5)
    dist = AnalyticDistances(collision_model_of(ur5))
    g = np.linspace(-0.15, 0.15, 7)
    pts = np.stack(np.meshgrid(g, g, np.linspace(-0.05, 0.3, 8), indexing="ij"), axis=-1).reshape(-1, 3)
    small = SerialCollisionMargin(mech, ur5, dist, collision_reach(mech, ur5, dist))(pts)
    large = SerialCollisionMargin(mech, ur5, dist, Reach(ur5, restarts=24, revolve=False))(pts)
    reached = (small[:, 0] > 0) & (large[:, 0] > 0)
    assert np.array_equal(small[reached, -1] > 0, large[reached, -1] > 0)
    assert 20 < (small[reached, -1] <= 0).sum() < reached.sum()
