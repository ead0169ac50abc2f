"""Obstacles (kinematics.generic.obstacles, issue 30 item 4): the two file formats, the capsule -
half-space closed form against coal, and a planar 2R arm of capsules beside a wall whose free area
is derived by hand, with the wall as a half-space, a box and a box mesh written by trimesh."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from kinematics.analyses.collision_volume import measure_collision_workspace
from kinematics.analyses.collisions import collision_model_of
from kinematics.errors import InvalidInputError, ModelFileError
from kinematics.generic.capsules import COAL, HALFSPACE, AnalyticDistances
from kinematics.generic.collision import CollisionModel
from kinematics.generic.obstacles import load_obstacles
from kinematics.mechanisms import mechanism_of
from kinematics.model.robot import load_robot

L1, L2, R = 0.4, 0.3, 0.02
"""The arm's link lengths and its capsules' radius [m]."""
WALL = 0.35
"""The wall's face: the solid is x >= WALL [m]."""


def _capsule(length: float) -> str:
    """A capsule of radius R along a link's x axis from 0 to `length`, as URDF can write one."""
    return (f'<collision><origin xyz="{length / 2} 0 0" rpy="0 1.5707963267948966 0"/><geometry><cylinder '
            f'radius="{R}" length="{length}"/></geometry></collision>'
            + "".join(f'<collision><origin xyz="{x} 0 0"/><geometry><sphere radius="{R}"/></geometry></collision>'
                      for x in (0.0, length)))


ARM = f"""<robot name="arm2r">
  <link name="base"/>
  <link name="link1">{_capsule(L1)}</link>
  <link name="link2">{_capsule(L2)}</link>
  <link name="tool"/>
  <joint name="joint1" type="revolute"><parent link="base"/><child link="link1"/><axis xyz="0 0 1"/>
    <limit lower="-3.141592653589793" upper="3.141592653589793" effort="1" velocity="1"/></joint>
  <joint name="joint2" type="revolute"><parent link="link1"/><child link="link2"/><origin xyz="{L1} 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-3.141592653589793" upper="3.141592653589793" effort="1" velocity="1"/></joint>
  <joint name="tool_joint" type="fixed"><parent link="link2"/><child link="tool"/><origin xyz="{L2} 0 0"/></joint>
</robot>"""

# the slab WALL <= x <= WALL + 0.2 over |y| <= 1 stops the arm exactly as the half-space does: every
# link segment starts at x = 0, so one that reaches past the slab crosses it within the arm's reach
HALF = f"obstacles:\n  - {{name: wall, halfspace: [-1, 0, 0, {-WALL}]}}\n"
BOX = f"obstacles:\n  - {{name: wall, box: [0.2, 2, 1], xyz: [{WALL + 0.1}, 0, 0]}}\n"
MESH = f"obstacles:\n  - {{name: wall, mesh: wall.stl, xyz: [{WALL + 0.1}, 0, 0]}}\n"


def _arc_overlap(a: tuple[float, float], b: tuple[float, float]) -> float:
    """Length of the intersection of two arcs (lo, hi) [rad] on the circle, each shorter than pi."""
    return sum(max(0.0, min(a[1], b[1] + s) - max(a[0], b[0] + s)) for s in (-2 * math.pi, 0.0, 2 * math.pi))


def _free_areas() -> tuple[float, float]:
    """(area per elbow branch, area of the union) [m^2] where the arm clears the wall, by hand.

    A capsule along a segment clears x >= WALL iff the segment's largest x is < c = WALL - R; the
    first segment starts at the origin (x = 0 < c), so the arm is free iff the elbow E and the tool
    P both have x < c. In polar coordinates P = (rho, phi) the elbows are at angles phi -+ gamma on
    the circle of radius L1, cos gamma = (L1^2 + rho^2 - L2^2) / (2 L1 rho). Beyond the wall: the
    tool where |phi| <= beta = acos(c / rho) (rho > c), an elbow where its angle is within
    alpha = acos(c / L1) of 0. Per branch the free angle is 2 pi - |A u B|, A = [-beta, beta],
    B = [-gamma - alpha, -gamma + alpha]; the union is free unless the tool or both elbows are
    beyond, 2 pi - |A u (B+ n B-)|. Areas: the integral of rho times the free angle over the
    annulus L1 - L2 <= rho <= L1 + L2 (a 1-D quadrature to 1e-13 of the closed-form angle)."""
    c = WALL - R
    alpha = math.acos(c / L1)

    def angles(rho: float) -> tuple[float, float]:
        gamma = math.acos(min(1.0, max(-1.0, (L1 * L1 + rho * rho - L2 * L2) / (2 * L1 * rho))))
        beta = math.acos(c / rho) if rho > c else 0.0
        tool, up, down = (-beta, beta), (-gamma - alpha, -gamma + alpha), (gamma - alpha, gamma + alpha)
        branch = 2 * math.pi - (2 * beta + 2 * alpha - _arc_overlap(tool, up))
        both = (max(up[0], down[0]), min(up[1], down[1]))  # one arc: gamma < 0.9 < pi - alpha here
        width = max(0.0, both[1] - both[0])
        union = 2 * math.pi - (2 * beta + width - (_arc_overlap(tool, both) if width > 0 else 0.0))
        return branch, union

    kinks = [c, math.sqrt(L1 * L1 - L2 * L2)]
    return tuple(quad(lambda rho, k=k: rho * angles(rho)[k], L1 - L2, L1 + L2, points=kinks, limit=400,
                      epsabs=1e-13)[0] for k in (0, 1))  # type: ignore[return-value]


@pytest.fixture
def arm(tmp_path):
    (tmp_path / "arm2r.urdf").write_text(ARM)
    return load_robot(tmp_path / "arm2r.urdf")


def _obstacles(tmp_path, text: str, name: str = "wall.yaml"):
    if "wall.stl" in text:
        import trimesh

        trimesh.creation.box(extents=(0.2, 2.0, 1.0)).export(tmp_path / "wall.stl")
    (tmp_path / name).write_text(text)
    return load_obstacles(tmp_path / name)


def test_the_free_area_by_hand_is_sane():
    """The hand-derived areas sit between the annulus's part left of the wall's stop line and
    nothing: the elbow constraint can only remove more, each branch more than the union."""
    branch, union = _free_areas()
    c = WALL - R
    left = (0.7 ** 2 * (math.pi - math.acos(c / 0.7)) + c * math.sqrt(0.49 - c * c)) - math.pi * 0.01
    assert 0 < branch < union < left


def test_arm_beside_a_half_space_wall_keeps_the_area_by_hand(arm, tmp_path):
    """A 2R arm of capsules (radius R) beside a half-space wall: the collision-free area per branch
    and of the union (each held within its error estimate) is the hand-derived one, the kinematic
    annulus is pi (0.7^2 - 0.1^2), and both links bind."""
    obstacles = _obstacles(tmp_path, HALF)
    cw = measure_collision_workspace(mechanism_of(arm), arm, step=0.01, rtol=1e-4, obstacles=obstacles,
                                     self_collisions=False)
    branch, union = _free_areas()
    ws = cw.workspace
    # rtol 1e-4 on the error estimates; the roots are bracketed to 1e-12 m; 3 sigma-like slack
    assert abs(ws.total - union) <= 3 * ws.error + 1e-9 and ws.total == pytest.approx(union, rel=3e-4)
    for k in range(2):
        assert abs(ws.result.estimate[k] - branch) <= 3 * ws.result.error[k] + 1e-9
    assert cw.kinematic == pytest.approx(math.pi * 0.48, rel=3e-4)
    assert {p.links for p in cw.pairs} == {("link1", "wall"), ("link2", "wall")}
    assert cw.collision["obstacles"] == ["wall"] and cw.collision["closed_form_pairs"] == 2


@pytest.mark.parametrize("text", [BOX, MESH], ids=["box", "mesh"])
def test_a_box_wall_and_its_mesh_give_the_half_spaces_area(arm, tmp_path, text):
    """The wall as a primitive box (coal) and as the same box written as an STL by trimesh (coal,
    through its hull and the mesh's own test): the same area as the half-space's, by hand."""
    obstacles = _obstacles(tmp_path, text)
    cw = measure_collision_workspace(mechanism_of(arm), arm, step=0.02, rtol=1e-3, obstacles=obstacles,
                                     self_collisions=False, check=False)
    assert AnalyticDistances(CollisionModel.from_robot(arm, obstacles=obstacles,
                                                       self_collisions=False)).kinds.tolist() == [COAL, COAL]
    union = _free_areas()[1]
    assert abs(cw.workspace.total - union) <= 3 * cw.workspace.error + 1e-9


def test_half_space_distances_are_coals(arm, tmp_path, rng):
    """The capsule - half-space closed form against coal on random configurations (to 1e-12 m:
    both are a plane's distance to the segment's ends), penetrations included."""
    cm = CollisionModel.from_robot(arm, obstacles=_obstacles(tmp_path, HALF), self_collisions=False)
    dist = AnalyticDistances(cm)
    assert dist.kinds.tolist() == [HALFSPACE, HALFSPACE]
    q = rng.uniform(-math.pi, math.pi, (4000, arm.model.nq))
    ours, ok = dist.closed_form(q)
    assert ok.all()
    coal_d = cm.distances(q)
    assert np.abs(ours - coal_d).max() < 1e-12
    assert (coal_d < 0).sum(axis=0).min() > 200  # penetrations were exercised
    # and by hand: link 2's largest x is the elbow's or the tool's
    elbow = L1 * np.cos(q[:, 0])
    tool = elbow + L2 * np.cos(q[:, 0] + q[:, 1])
    assert np.abs(ours[:, cm.pair_links.index(("link2", "wall"))]
                  - (WALL - np.maximum(elbow, tool) - R)).max() < 1e-12


def test_urdf_and_yaml_obstacles_are_the_same(arm, tmp_path, rng):
    """A URDF of fixed bodies (a chain of fixed joints, a cylinder + end spheres read as a capsule)
    and the YAML listing the same shapes give the same pairs and distances."""
    urdf = """<robot name="scene"><link name="world"/>
  <link name="shelf"><collision><origin xyz="0.1 0 0"/><geometry><box size="0.1 0.4 0.3"/></geometry></collision></link>
  <link name="bar">
    <collision><geometry><cylinder radius="0.03" length="0.2"/></geometry></collision>
    <collision><origin xyz="0 0 0.1"/><geometry><sphere radius="0.03"/></geometry></collision>
    <collision><origin xyz="0 0 -0.1"/><geometry><sphere radius="0.03"/></geometry></collision></link>
  <joint name="a" type="fixed"><parent link="world"/><child link="shelf"/><origin xyz="0.4 0.2 0" rpy="0 0 0.3"/></joint>
  <joint name="b" type="fixed"><parent link="shelf"/><child link="bar"/><origin xyz="-0.6 -0.4 0"/></joint>
</robot>"""
    # the YAML's poses, composed by hand: the shelf's frame is at (0.4, 0.2) turned 0.3 about z;
    # the box 0.1 along its x, the bar at (-0.6, -0.4) in it
    c, s = math.cos(0.3), math.sin(0.3)
    box = (0.4 + 0.1 * c, 0.2 + 0.1 * s)
    bar = (0.4 - 0.6 * c + 0.4 * s, 0.2 - 0.6 * s - 0.4 * c)
    yaml_text = (f"obstacles:\n  - {{name: shelf, box: [0.1, 0.4, 0.3], xyz: [{box[0]!r}, {box[1]!r}, 0], "
                 f"rpy: [0, 0, 0.3]}}\n  - {{name: bar, capsule: [0.03, 0.2], xyz: [{bar[0]!r}, {bar[1]!r}, 0]}}\n")
    from_urdf = _obstacles(tmp_path, urdf, "scene.urdf")
    from_yaml = _obstacles(tmp_path, yaml_text)
    assert from_urdf.names == from_yaml.names == ("shelf", "bar")
    q = rng.uniform(-math.pi, math.pi, (500, arm.model.nq))
    a, b = (CollisionModel.from_robot(arm, obstacles=o, self_collisions=False) for o in (from_urdf, from_yaml))
    assert a.pair_links == b.pair_links
    assert np.abs(a.distances(q) - b.distances(q)).max() < 1e-9  # coal's GJK at 1e-10 m


def test_obstacle_pairs_join_self_pairs_and_are_never_touching(tmp_path):
    """With self-collisions on, the robot's own pairs stay and each moving body meets each
    obstacle; an obstacle touching the robot at the reference pose stays checked; obstacles alone
    check only the obstacle pairs; a robot with nothing moving that has a shape is refused."""
    from .test_collision_workspace import WALL as ROBOT

    (tmp_path / "r.urdf").write_text(ROBOT)
    robot = load_robot(tmp_path / "r.urdf")
    # a ball where the stretched arm's tool is at the neutral pose (x = 0.7): touching there
    obstacles = _obstacles(tmp_path, "obstacles:\n  - {name: ball, sphere: 0.1, xyz: [0.7, 0, 0]}\n")
    both = CollisionModel.from_robot(robot, obstacles=obstacles)
    assert set(both.pair_links) == {("tool", "ball")}  # base - tool touches at the reference: left out
    assert both.distances(np.zeros((1, robot.model.nq)))[0, 0] < 0
    with_self = CollisionModel.from_robot(robot, obstacles=obstacles, exclude_touching=False)
    assert set(with_self.pair_links) == {("base", "tool"), ("tool", "ball")}
    alone = collision_model_of(robot, obstacles, self_collisions=False)
    assert alone.pair_links == (("tool", "ball"),)
    (tmp_path / "bare.urdf").write_text(ARM.replace(_capsule(L1), "").replace(_capsule(L2), ""))
    with pytest.raises(InvalidInputError, match="no collision shape on a moving body"):
        collision_model_of(load_robot(tmp_path / "bare.urdf"), obstacles, self_collisions=False)
    clash = _obstacles(tmp_path, "obstacles:\n  - {name: tool, sphere: 0.1}\n", "clash.yaml")
    with pytest.raises(InvalidInputError, match="also a name of the robot"):
        CollisionModel.from_robot(robot, obstacles=clash)


@pytest.mark.parametrize(("name", "text", "match"), [
    ("a.yaml", "obstacles:\n  - {name: x, cone: [1, 2]}\n", "exactly one shape"),
    ("b.yaml", "obstacles:\n  - {name: x, box: [1, 0, 1]}\n", "sizes must be positive"),
    ("c.yaml", "obstacles:\n  - {name: x, mesh: nowhere.stl}\n", "not found"),
    ("d.yaml", "obstacles:\n  - {name: x, sphere: 1}\n  - {name: x, sphere: 2}\n", "given twice"),
    ("e.yaml", "walls: []\n", "under 'obstacles:'"),
    ("f.urdf", ('<robot name="s"><link name="w"/><link name="m"><collision><geometry><sphere radius="1"/></geometry>'
               '</collision></link><joint name="j" type="revolute"><parent link="w"/><child link="m"/>'
               '<limit lower="0" upper="1" effort="1" velocity="1"/></joint></robot>'), "do not move"),
    ("g.urdf", ('<robot name="s"><link name="w"><collision><geometry><capsule radius="1" length="1"/></geometry>'
               '</collision></link></robot>'), "not read"),
    ("h.txt", "", "must be a .urdf or a .yaml"),
    ("i.yaml", "obstacles:\n  - {name: x, sphere: 1, rpy: [0, 0]}\n", "obstacle x: rpy: expected 3"),  # was "size:"
    ("j.yaml", "obstacles:\n  - {name: x, sphere: 1, xyz: [0, .nan, 0]}\n", "obstacle x: xyz: expected 3"),
    # sizes as a mapping: Python's "float() argument must be ... not 'dict'" before
    ("k.yaml", "obstacles:\n  - {name: x, cylinder: {radius: 0.05, length: 1}}\n",
     "obstacle x: size: expected 2 finite numbers, got {'radius'"),
])
def test_bad_obstacle_files_are_refused(tmp_path, name, text, match):
    (tmp_path / name).write_text(text)
    with pytest.raises(ModelFileError, match=match):
        load_obstacles(tmp_path / name)


@pytest.mark.parametrize(("name", "data", "match"), [
    ("a.yaml", b"\xff\xfe\x00 not text", "not UTF-8 text"),
    ("b.urdf", b"\xff\xfe\x00 not text", "not UTF-8 text"),
    ("c.yaml", b"obstacles:\n  - {name: a, box: [1, 2\n", "not YAML"),
    ("d.yaml", b"obstacles:\n  - {name: part, mesh: bad.stl}\n", "obstacle part: mesh: cannot load"),
    ("e.urdf", (b'<robot name="s"><link name="w"/><link name="m"><collision><geometry><mesh filename="bad.stl"/>'
                b'</geometry></collision></link><joint name="j" type="fixed"><parent link="w"/><child link="m"/>'
                b'</joint></robot>'), "not loaded: Could not load resource"),
])
def test_unreadable_obstacle_files_are_refused_in_one_line(tmp_path, name, data, match):
    # the CLI prints the message as its one stderr line: a decoding error and a mesh file coal
    # cannot read (in a URDF) escaped as tracebacks, and the YAML parser's and coal's mesh loader's
    # messages spanned several lines
    (tmp_path / "bad.stl").write_text("solid x\n")
    (tmp_path / name).write_bytes(data)
    with pytest.raises(ModelFileError, match=match) as info:
        load_obstacles(tmp_path / name)
    assert "\n" not in str(info.value), str(info.value)


def test_a_robot_mesh_coal_cannot_read_is_one_line_of_bad_input(tmp_path, capsys):
    # the mesh file is found (so not refused as missing) but is no mesh: Pinocchio's loader raised
    # coal's multi-line ValueError, which escaped the CLI as a traceback
    from .test_cli import run

    (tmp_path / "bad.stl").write_text("solid x\n")
    (tmp_path / "arm.urdf").write_text(ARM.replace(_capsule(L1), '<collision><geometry><mesh filename="bad.stl"/>'
                                                                 '</geometry></collision>'))
    code, out, err = run(capsys, "workspace-volume", str(tmp_path / "arm.urdf"), "--collisions", "--step", "0.1")
    assert code == 2 and out == "" and err.count("\n") == 1, err
    assert "collision geometry not loaded: Could not load resource" in err


@pytest.mark.parametrize("where", ["obstacle", "robot"])
def test_a_flat_mesh_is_refused_not_a_crash(tmp_path, where):
    # a box mesh squashed to 1e-8 of its size along z (or to 0: the same) crashed the process in
    # coal's convex hull (a segmentation fault, exit -11); in a subprocess, as it did
    import subprocess
    import sys

    import trimesh

    trimesh.creation.box(extents=(0.2, 0.2, 0.2)).export(tmp_path / "box.stl")
    flat = '<mesh filename="box.stl" scale="1 1 1e-8"/>'
    (tmp_path / "arm.urdf").write_text(ARM if where == "obstacle" else ARM.replace(
        _capsule(L1), f'<collision><geometry>{flat}</geometry></collision>'))
    (tmp_path / "o.yaml").write_text("obstacles:\n  - {name: plate, mesh: box.stl, scale: [1, 1, 1.0e-8], "
                                     "xyz: [0.3, 0, 0]}\n")
    extra = ["--obstacles", str(tmp_path / "o.yaml")] if where == "obstacle" else ["--collisions"]
    proc = subprocess.run([sys.executable, "-m", "kinematics", "workspace-volume", str(tmp_path / "arm.urdf"),
                           *extra, "--step", "0.1"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and proc.stdout == "" and proc.stderr.count("\n") == 1, (proc.returncode, proc.stderr)
    assert "flat: its 8 vertices" in proc.stderr


def test_cli_obstacles_alone_and_with_collisions(arm, tmp_path, capsys):
    """`workspace-volume --obstacles` (alone: robot-obstacle pairs only) reports the free area by
    hand (to its error estimate at rtol 1e-3) and the obstacles; a bad file is one line, exit 2."""
    from .test_cli import run, run_json

    _obstacles(tmp_path, HALF)
    urdf = str(tmp_path / "arm2r.urdf")
    code, d, _ = run_json(capsys, "workspace-volume", urdf, "--obstacles", str(tmp_path / "wall.yaml"),
                          "--step", "0.01", "--rtol", "1e-3")
    assert code == 0
    c = d["collisions"]
    assert c["obstacles"] == ["wall"] and c["pairs_checked"] == 2
    assert abs(d["area_m2"] - _free_areas()[1]) <= 3 * d["error_estimate"] + 1e-9
    code, d2, _ = run_json(capsys, "workspace-volume", urdf, "--obstacles", str(tmp_path / "wall.yaml"),
                           "--collisions", "--step", "0.02", "--rtol", "1e-2")
    assert code == 0 and d2["collisions"]["pairs_checked"] == 2  # adjacent links: no self pair
    assert [e["reason"] for e in d2["collisions"]["excluded"]] == []
    (tmp_path / "bad.yaml").write_text("obstacles: 3\n")
    code, out, err = run(capsys, "workspace-volume", urdf, "--obstacles", str(tmp_path / "bad.yaml"))
    assert code == 2 and "under 'obstacles:'" in err and len(err.strip().splitlines()) == 1


def test_a_usable_region_emptied_by_an_obstacle_does_not_blame_kappa(tmp_path, capsys):
    # the error read "kappa_max: no grid point is usable ...", with kappa at its default, when a
    # sphere around the whole delta made every point collide
    from .test_cli import run

    (tmp_path / "blob.yaml").write_text("obstacles:\n  - {name: blob, sphere: 10.0}\n")
    code, out, err = run(capsys, "usable-workspace", "delta", "--shape", "cube", "--obstacles",
                         str(tmp_path / "blob.yaml"), "--step", "0.1")
    assert code == 2 and out == "" and err.count("\n") == 1, err
    assert "collision-free where checked" in err and "kappa_max:" not in err


def test_usable_cube_above_a_floor_is_the_hand_fields(tmp_path, capsys):
    """usable-workspace with obstacles: p2us-results (mode ---) above a floor z >= -0.62 m. The
    lowest body is the platform's sphere (radius d + platform overhang = 0.028 + 0.02 m, the
    generator's documented sizes), so the collision margin's sign is that of z - (-0.62 + 0.048):
    the usable cube with the floor is the one of the hand field min(u, z + 0.572) (the search uses
    only signs: the same cube), and the floor binds (the cube without it reaches lower)."""
    from kinematics.analyses.usable import largest_shape, usable, usable_field

    from .test_cli import run_json

    robot = load_robot("p2us-results")
    mech = mechanism_of(robot)
    _obstacles(tmp_path, "obstacles:\n  - {name: floor, halfspace: [0, 0, 1, -0.62]}\n")
    code, got, _ = run_json(capsys, "usable-workspace", "p2us-results", "--shape", "cube", "--step", "0.05",
                            "--obstacles", str(tmp_path / "wall.yaml"))
    assert code == 0 and got["collisions"]["obstacles"] == ["floor"]
    assert got["collisions"]["pairs_checked"] == 7  # the platform and six rods move; the rails do not
    top = -0.62 + mech.params.d + 0.02
    u = usable_field(mech, "---")
    lo, hi = mech.bounding_box("all")
    hand = largest_shape(lambda p: np.minimum(u(p), p[:, 2] - top), lo, hi, "cube", step=0.05)
    edge = got["size_m"]["edge_m"]
    assert got["center_m"] == pytest.approx(hand.center.tolist(), abs=1e-12) and edge == pytest.approx(hand.size[0],
                                                                                                       abs=1e-12)
    assert got["center_m"][2] - edge / 2 >= top - got["check"]["spacing_m"]  # it stands on the floor's stop
    free = usable(mech, "cube", step=0.05)
    assert free.center[2] - free.size[0] / 2 < top - 0.02


FLOOR = "obstacles:\n  - {name: floor, halfspace: [0, 0, 1, -0.62]}\n"


def test_singular_points_below_a_floor_are_flagged(tmp_path, capsys):
    """singularities --obstacles: p2us-results' type II/III points inside its workspace (mode ---)
    are flagged colliding exactly where the platform's sphere (radius d + 0.02 m) crosses the
    floor z = -0.62 m, by hand, and where coal finds a pair overlapping at the configuration built
    point by point from `joint_values` (the path the flags do not take)."""
    from .test_cli import run_json

    robot = load_robot("p2us-results")
    mech = mechanism_of(robot)
    _obstacles(tmp_path, FLOOR)
    code, d, _ = run_json(capsys, "singularities", "p2us-results", "--step", "0.02", "--obstacles",
                          str(tmp_path / "wall.yaml"))
    assert code == 0
    pts = np.array([p["position"] for p in d["singular_points"]])
    flags = np.array([p["colliding"] for p in d["singular_points"]])
    hand = pts[:, 2] - (mech.params.d + 0.02) < -0.62
    assert 50 < hand.sum() < len(hand) - 50  # both kinds are exercised
    assert (flags == hand).all()
    cm = CollisionModel.from_robot(robot, obstacles=load_obstacles(tmp_path / "wall.yaml"), self_collisions=False)
    modes = [p["mode"] for p in d["singular_points"]]
    q = np.array([robot.configuration([mech.joint_values(p, m)[n] for n in robot.joint_names])
                  for p, m in zip(pts, modes, strict=True)])
    assert ((cm.distances(q).min(axis=1) < 0) == flags).all()
    c = d["collisions"]
    assert c["interior_points"] == len(pts) and c["colliding_points"] == hand.sum()
    assert c["any_inside_collision_free"]


def test_singularities_with_collisions_and_no_interior_point(capsys):
    """singularities --collisions where no type II/III point lies inside the workspace (delta, mode
    ---, 4 cm grid: its few type II/III points sit on the grid's reach boundary): an answer with
    zero points flagged, not a crash on the empty list (it raised a ValueError reshaping it)."""
    from .test_cli import run, run_json

    code, d, err = run_json(capsys, "singularities", "delta", "--collisions", "--step", "0.04", "--modes=---")
    assert code == 0 and err == ""
    assert d["singularities"]["type_II"]["locus_points"] > 0  # singular points exist, none inside
    assert d["singular_points"] == []
    c = d["collisions"]
    assert (c["interior_points"], c["colliding_points"], c["any_inside_collision_free"]) == (0, 0, False)
    code, out, _ = run(capsys, "singularities", "delta", "--collisions", "--step", "0.04", "--modes=---")
    assert code == 0 and "colliding: 0 of 0" in out


def test_cli_points_are_the_collision_free_ones(arm, tmp_path, capsys):
    """`workspace-volume --obstacles --points`: the listed grid points are those where the arm
    clears the wall in some elbow (by hand: the tool and that elbow at x < WALL - R), up to the
    points within 1e-9 m of a boundary."""
    from .test_cli import run_json

    _obstacles(tmp_path, HALF)
    out = tmp_path / "pts.npy"
    code, _, _ = run_json(capsys, "workspace-volume", str(tmp_path / "arm2r.urdf"), "--obstacles",
                          str(tmp_path / "wall.yaml"), "--step", "0.02", "--rtol", "1e-2", "--points", str(out))
    assert code == 0
    listed = np.load(out)
    c = WALL - R
    lo, hi = -0.7, 0.7
    axis = np.arange(lo + 0.01, hi, 0.02)
    grid = np.stack(np.meshgrid(axis, axis, indexing="ij"), axis=-1).reshape(-1, 2)
    rho = np.linalg.norm(grid, axis=1)
    phi = np.arctan2(grid[:, 1], grid[:, 0])
    gamma = np.arccos(np.clip((L1 ** 2 + rho ** 2 - L2 ** 2) / (2 * L1 * np.maximum(rho, 1e-12)), -1, 1))
    elbow = np.minimum(L1 * np.cos(phi + gamma), L1 * np.cos(phi - gamma))
    free = (rho >= L1 - L2) & (rho <= L1 + L2) & (grid[:, 0] < c) & (elbow < c)
    near = (np.abs(rho - (L1 - L2)) < 1e-9) | (np.abs(rho - (L1 + L2)) < 1e-9)
    got = {tuple(np.round(p, 9)) for p in listed}
    want = {tuple(np.round(p, 9)) for p in grid[free & ~near]}
    assert want <= got and got <= {tuple(np.round(p, 9)) for p in grid[free]}
    assert 100 < len(got) < len(grid)


def test_a_link_pair_binding_through_two_shapes_is_told_apart(tmp_path, capsys):
    """link2 with a sphere of radius 2R at its middle beside its capsule: both of its shapes bind
    against the wall, each removing its own area; the report's table names their shapes (it
    printed "link2 - wall" twice), a pair binding through one shape stays as it was."""
    from .test_cli import run

    arm = ARM.replace('<link name="link2">', f'<link name="link2"><collision><origin xyz="{L2 / 2} 0 0"/>'
                                             f'<geometry><sphere radius="{2 * R}"/></geometry></collision>')
    (tmp_path / "arm.urdf").write_text(arm)
    _obstacles(tmp_path, HALF)
    code, out, _ = run(capsys, "workspace-volume", str(tmp_path / "arm.urdf"), "--obstacles",
                       str(tmp_path / "wall.yaml"), "--step", "0.02", "--rtol", "1e-2")
    assert code == 0
    rows = [line.split("  ")[0] for line in out.splitlines() if line.startswith("link")]
    assert sorted(rows) == ["link1 - wall", "link2 - wall (link2_0 - wall)", "link2 - wall (link2_1 - wall)"]
