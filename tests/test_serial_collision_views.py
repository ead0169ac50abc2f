"""Collision-aware views of serial arms (issue 30 item 5): `show ROBOT --workspace --collisions /
--obstacles` (`serial_collisions.collision_grid`: the reached grid points split into collision-free
and colliding by binding pair) and `workspace-volume --collisions --plot`, held to the conditions
by hand of tests/test_serial_collisions.py's arms (the planar 2R arm beside a wall, the 3R arm
beside the wall in 3-D and with a post on its turret on its profile) and, for the ur5's meshes, to
coal's own distances at the configurations found."""

from __future__ import annotations

import re

import numpy as np

from kinematics.analyses.collisions import collision_model_of, margin_builder
from kinematics.analyses.serial_collisions import ESCALATE, collision_grid
from kinematics.generic.obstacles import load_obstacles
from kinematics.mechanisms import mechanism_of
from kinematics.mechanisms.serial.mechanism import SerialArm
from kinematics.model.robot import load_robot
from kinematics.views import meshcat as viz

from .test_cli import run, run_json
from .test_collision_obstacles import ARM, HALF
from .test_serial_collisions import L1, L2, WALL, R, _post_clearance, _wall_clearance, arm3  # noqa: F401 (a fixture)

SURE = 1e-6
"""[m] Points whose clearance by hand is within this of zero are left out: the search reaches to
1e-10 m, the distances are exact to ~1e-15 m, so a sign there is rounding's to decide."""


def test_planar_arm_grid_is_split_as_by_hand(tmp_path):
    """The planar 2R arm as a generic serial arm (planar search) beside the wall, on a 0.023 m grid
    of its plane: the points reached are the annulus's, a point is free iff the tool and one of its
    two elbows lie at x < WALL - R, and every colliding point is bound by an arm - wall pair."""
    (tmp_path / "arm.urdf").write_text(ARM)
    (tmp_path / "wall.yaml").write_text(HALF)
    robot = load_robot(tmp_path / "arm.urdf")
    cm = collision_model_of(robot, load_obstacles(tmp_path / "wall.yaml"), self_collisions=False)
    g = collision_grid(SerialArm(robot), robot, cm, 0.023)
    assert g.mode == "planar" and g.points.shape[1] == 2 and g.axis is None
    axes = [np.arange(-0.7 + 0.023 / 2, 0.7, 0.023)] * 2  # the reach disc's box, cell centres
    p = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 2)
    rho, phi = np.hypot(p[:, 0], p[:, 1]), np.arctan2(p[:, 1], p[:, 0])
    gamma = np.arccos(np.clip((L1 * L1 + rho * rho - L2 * L2) / (2 * L1 * np.maximum(rho, 1e-12)), -1, 1))
    c = WALL - R
    elbow = np.maximum(c - L1 * np.cos(phi - gamma), c - L1 * np.cos(phi + gamma))
    shell = np.minimum(rho - (L1 - L2), L1 + L2 - rho)
    clear = np.minimum(np.minimum(c - p[:, 0], elbow), shell)
    key = {tuple(np.round(x, 9)): n for n, x in enumerate(p)}
    at = np.array([key[tuple(np.round(x, 9))] for x in g.points])
    sure = (np.abs(clear) > SURE) & (np.abs(shell) > SURE)
    assert {n for n in at if abs(shell[n]) > SURE} == set(np.flatnonzero(shell > SURE))  # reached: the annulus
    ok = sure[at]
    assert ok.mean() > 0.99 and g.free[ok].any() and (~g.free[ok]).any()
    assert np.array_equal(g.free[ok], clear[at][ok] > 0)
    assert g.pair[g.free].max() == -1 and all("wall" in cm.pair_links[k] for k in g.pair[~g.free])
    # the JSON block (`show --json`): both arm - wall pairs bind, the more frequent first
    c = g.as_dict()
    assert (c["grid_points"], c["reached"], c["free"]) == (len(p), len(g.points), int(g.free.sum()))
    links = [cm.pair_links[k] for k in g.pair[~g.free]]
    want = sorted(((list(k), links.count(k)) for k in set(links)), key=lambda x: -x[1])
    assert len(want) == 2 and want[0][1] > want[1][1]
    assert [(b["links"], b["points"]) for b in c["binding_pairs"]] == want


def test_spatial_arm_grid_beside_a_wall_is_split_as_by_hand(arm3):  # noqa: F811
    """The 3R arm beside the wall (searched in 3-D: the wall pairs change with the yaw), on the
    default grid (24 per axis over the reach ball's box): reached iff in the shell, free iff the
    tool and one elbow clear the wall at the point's azimuth (`_wall_clearance`)."""
    robot = load_robot(arm3 / "arm3.urdf")
    cm = collision_model_of(robot, load_obstacles(arm3 / "wall.yaml"), self_collisions=False)
    g = collision_grid(mechanism_of(robot), robot, cm)
    assert g.mode == "spatial" and g.grid_points == 24**3 and abs(g.step - 1.4 / 24) < 1e-12
    p, shell, clear, sure = _wall_grid_by_hand()
    got = {tuple(np.round(x, 9)) for x in g.points}
    want = {tuple(np.round(x, 9)) for x in p[sure & (shell > 0)]}
    assert want <= got and not (got - want) & {tuple(np.round(x, 9)) for x in p[sure & (shell < 0)]}
    key = {tuple(np.round(x, 9)): n for n, x in enumerate(p)}
    at = np.array([key[tuple(np.round(x, 9))] for x in g.points])
    ok = sure[at]
    assert ok.mean() > 0.99 and 500 < (~g.free[ok]).sum() < ok.sum() - 500
    assert np.array_equal(g.free[ok], clear[at][ok] > 0)
    assert {cm.pair_links[k] for k in g.pair[~g.free]} <= {("link1", "wall"), ("link2", "wall")}


def _wall_grid_by_hand() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The 3R arm beside the wall on the view's default grid (24 cell centres per axis over the
    reach ball's box [-0.7, 0.7]^3): the points, the shell's margin (> 0: reached), the clearance
    by hand (`_wall_clearance`, > 0: free) and where both are away from zero (`SURE`)."""
    step = 1.4 / 24
    axis = np.arange(-0.7 + step / 2, 0.7, step)
    p = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    r = np.linalg.norm(p, axis=1)
    shell = np.minimum(r - (L1 - L2), L1 + L2 - r)
    clear = _wall_clearance(p)
    return p, shell, clear, (np.abs(clear) > SURE) & (np.abs(shell) > SURE)


def test_revolved_arm_grid_with_a_post_is_its_profile(arm3):  # noqa: F811
    """The 3R arm with a post on its turret (the only pair turns with the yaw): the grid is the
    profile's half-plane at azimuth 0, 48 points along z; a point is free iff one elbow keeps link
    2 clear of the post by hand (`_post_clearance`), else the pair turret - link2 binds."""
    robot = load_robot(arm3 / "arm3p.urdf")
    cm = collision_model_of(robot)
    g = collision_grid(mechanism_of(robot), robot, cm)
    assert g.mode == "revolved" and g.axis is not None and abs(g.step - 1.4 / 48) < 1e-12
    reach = g.margin.reach
    prof = reach.profile_of(g.points)
    assert np.allclose(reach.profile_world(prof), g.points, atol=1e-12)  # on the half-plane at azimuth 0
    rho, z = prof[:, 0], prof[:, 1]
    r = np.hypot(rho, z)
    gamma = np.arccos(np.clip((L1 * L1 + r * r - L2 * L2) / (2 * L1 * r), -1, 1))
    a = np.arctan2(z, rho)
    clear = _post_clearance(rho, z, a - gamma, a + gamma)
    ok = (np.abs(clear) > SURE) & (np.minimum(r - (L1 - L2), L1 + L2 - r) > SURE)
    assert ok.mean() > 0.97 and 20 < (~g.free[ok]).sum() < ok.sum() - 20
    assert np.array_equal(g.free[ok], clear[ok] > 0)
    assert {cm.pair_links[k] for k in g.pair[~g.free]} == {("turret", "link2")}
    scene = viz.serial_view(robot, collisions=cm)
    labels = [label for label, _ in scene.legend]
    free = [m for m in (re.search(r"collision-free workspace \((\d+) profile points; a \(rho, z\) profile grid "
                                  r"turned at (\d+) azimuths", x) for x in labels) if m]
    assert len(free) == 1 and int(free[0].group(1)) == int(g.free.sum()) and int(free[0].group(2)) >= 4
    assert any(f"colliding: turret - link2 binds ({int((~g.free).sum())} profile points)" in x for x in labels)


def test_ur5_grid_claims_hold_by_coal(ur5):
    """The ur5 (meshes) with self-collisions on the view's default grid: every point claimed free
    has its configuration at the point with every pair apart by coal's own distances
    (`CollisionModel.distances`); every point claimed colliding has the reported pair overlapping
    at its configuration, and every configuration the search found there (the first 4 x restarts
    seeds' descents) collides."""
    mech = mechanism_of(ur5)
    model = collision_model_of(ur5)
    g = collision_grid(mech, ur5, model)
    reach = g.margin.reach
    assert g.mode == "spatial" and 2000 < len(g.points) < 5000
    free, said = np.flatnonzero(g.free), np.flatnonzero(~g.free)
    assert (np.abs(reach.chain_fk(g.q) - g.points) <= 1e-9).all()  # REACH_TOL = 1e-10
    assert (model.distances(g.margin.full_configurations(g.q[free])).min(axis=1) > 0).all()
    d = model.distances(g.margin.full_configurations(g.q[said]))
    assert len(said) > 0 and (d[np.arange(len(said)), g.pair[said]] < 0).all()
    Qs, ok = reach.solutions(g.points[said], 0, ESCALATE * reach.restarts)
    for n in range(len(said)):
        assert (model.distances(g.margin.full_configurations(Qs[n][ok[n]])).min(axis=1) <= 0).all()


def _slices(fig):
    """The count maps of `spatial_workspace`'s three slices: (z, counts (nx, ny)) each."""
    out = []
    for ax in fig.axes[:3]:
        z = float(re.match(r"z = (\S+) m", ax.get_title()).group(1))
        out.append((z, np.ma.filled(ax.collections[0].get_array(), 0).reshape(-1)))
    return out


def test_plot_maps_the_collision_free_points_by_hand(arm3):  # noqa: F811
    """`workspace-volume --plot`'s figure of a serial arm: with the wall's collision margin each
    slice's map is 1 exactly where the 3R arm reaches the point clear of the wall by hand; without
    it (the kinematic figure) exactly where it reaches the point (the shell)."""
    from kinematics.views import plots

    robot = load_robot(arm3 / "arm3.urdf")
    mech = mechanism_of(robot)
    cm = collision_model_of(robot, load_obstacles(arm3 / "wall.yaml"), self_collisions=False)
    step = 0.05
    plots.headless()
    lo, hi = mech.bounding_box("all")
    x, y = (np.arange(lo[k], hi[k] + step / 2, step) for k in range(2))
    X, Y = np.meshgrid(x, y, indexing="ij")
    for margin, what in [(margin_builder(mech, robot, cm)(mech.branches), "collision-free"), (None, "")]:
        fig = plots.spatial_workspace(mech, "all", step, branch_margin=margin, what=what)
        assert "tool reaches" in fig.axes[-1].get_ylabel()
        for z, count in _slices(fig):
            p = np.stack([X.ravel(), Y.ravel(), np.full(X.size, z)], axis=1)
            r = np.linalg.norm(p, axis=1)
            want = _wall_clearance(p) if what else np.minimum(r - (L1 - L2), L1 + L2 - r)
            ok = np.abs(want) > 1e-3
            assert ok.mean() > 0.95 and (want[ok] > 0).sum() > 50
            assert np.array_equal(count[ok] == 1, want[ok] > 0)


def test_cli_show_and_plot_of_a_serial_arm_with_obstacles(arm3, capsys):  # noqa: F811
    """`show ARM --workspace --obstacles` exports the colliding clouds by pair, the free cloud and
    the wall (JSON: its stable keys); `workspace-volume --obstacles --plot` writes a figure; too
    fine a step for either is refused in one line, exit 2, before any run."""
    urdf, wall, html = str(arm3 / "arm3.urdf"), str(arm3 / "wall.yaml"), arm3 / "scene.html"
    code, d, err = run_json(capsys, "show", urdf, "--workspace", "--obstacles", wall, "--export", str(html))
    assert code == 0, err
    assert set(d) == {"robot", "export", "warnings", "skipped_visuals", "collisions", "plane"}
    assert d["export"] == str(html)
    _grid_counts_hold_by_hand(d["collisions"])
    page = html.read_text()
    assert "colliding: link2 - wall binds" in page and "obstacle wall" in page
    assert "collision-free workspace (" in page and "13,824 points searched" in page
    png = arm3 / "w.png"
    code, _, err = run(capsys, "workspace-volume", urdf, "--obstacles", wall, "--step", "0.1", "--rtol", "5e-2",
                       "--plot", str(png))
    assert code == 0 and png.stat().st_size > 10_000, err
    for argv, needle in [(["show", urdf, "--workspace", "--obstacles", wall, "--step", "1e-3", "--export",
                           str(arm3 / "x.html")], "--step"),
                         (["workspace-volume", urdf, "--obstacles", wall, "--step", "0.001", "--plot",
                           str(arm3 / "x.png")], "--plot")]:
        code, _, err = run(capsys, *argv)
        assert code == 2 and needle in err and len(err.strip().splitlines()) == 1, err
    assert not (arm3 / "x.html").exists() and not (arm3 / "x.png").exists()


def _grid_counts_hold_by_hand(c):
    """`show --json`'s collisions block of the 3R arm beside the wall: its grid's counts are those
    by hand (`_wall_grid_by_hand`) up to the points within SURE of a boundary, and every colliding
    point is bound by an arm - wall pair, the most frequent pair first."""
    _, shell, clear, sure = _wall_grid_by_hand()
    unsure = int((~sure).sum())
    assert c["mode"] == "spatial" and c["grid_points"] == 24**3 and abs(c["step_m"] - 1.4 / 24) < 1e-12
    assert c["pairs_checked"] == 2 and c["obstacles"] == ["wall"]
    assert c["free"] + c["colliding"] == c["reached"]
    assert abs(c["reached"] - int((shell > 0).sum())) <= unsure
    assert abs(c["free"] - int(((shell > 0) & (clear > 0)).sum())) <= unsure
    assert abs(c["colliding"] - int(((shell > 0) & (clear <= 0)).sum())) <= unsure < 0.01 * c["colliding"]
    counts = [b["points"] for b in c["binding_pairs"]]
    assert sum(counts) == c["colliding"] and counts == sorted(counts, reverse=True)
    assert {tuple(b["links"]) for b in c["binding_pairs"]} <= {("link1", "wall"), ("link2", "wall")}


def test_cli_show_reports_a_serial_arms_collision_grid(arm3, capsys):  # noqa: F811
    """`show ARM --workspace --obstacles` without --json: the grid's counts as a short report with
    units (the step in m, the points by kind), the same counts as its JSON block."""
    urdf, wall, html = str(arm3 / "arm3.urdf"), str(arm3 / "wall.yaml"), str(arm3 / "human.html")
    code, out, err = run(capsys, "show", urdf, "--workspace", "--obstacles", wall, "--export", html)
    assert code == 0, err
    lines = dict(re.findall(r"^(\S[^:\n]*?) +: (.*)$", out, flags=re.M))
    c = {"grid_points": lines["grid points searched"], "reached": lines["reached by the search"],
         "free": lines["collision-free"], "colliding": lines["colliding"]}
    counts = {k: int(v.split()[0].replace(",", "")) for k, v in c.items()}
    assert all(v.split()[1] == "points" for k, v in c.items() if k != "grid_points")
    assert re.search(r"^collision check on a 3-D grid, step 0\.05833 m$", out, flags=re.M)
    _grid_counts_hold_by_hand({"mode": "spatial", "step_m": 1.4 / 24, "pairs_checked": int(lines["pairs checked"]),
                               "obstacles": [lines["obstacles"]], **counts,
                               "binding_pairs": [{"links": m[0].split(" - "), "points": int(m[1].replace(",", ""))}
                                                 for m in re.findall(r"(\w+ - \w+) \(([\d,]+)\)",
                                                                     lines["binding pairs"])]})
    assert out.rstrip().endswith(f"wrote {html}")


def test_a_link_with_two_shapes_is_one_cloud(tmp_path):
    """A link whose two shapes both bind somewhere (link 2's capsule where the tool is in the wall,
    a ball of radius 0.05 m on its elbow end, which holds link 1's end, where the elbow is) is
    drawn as one cloud, labelled once, holding every point where either binds."""
    from kinematics.analyses.collisions import collision_map

    ball = '<collision><geometry><sphere radius="0.05"/></geometry></collision>'
    (tmp_path / "arm.urdf").write_text(ARM.replace('<link name="link2">', '<link name="link2">' + ball))
    (tmp_path / "wall.yaml").write_text(HALF)
    robot = load_robot(tmp_path / "arm.urdf")
    cm = collision_model_of(robot, load_obstacles(tmp_path / "wall.yaml"), self_collisions=False)
    mech, step = mechanism_of(robot), 0.023
    scene = viz.scara_view(robot, workspace=True, collisions=cm, step=step)
    lo, hi = mech.bounding_box("all")
    axes = [np.arange(lo[k] + step / 2, hi[k], step) for k in range(2)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 2)
    pts = pts[(mech.margin(None, "all")(pts)[:, :-1] >= 0).any(axis=1)]
    margin, pair = collision_map(mech, robot, cm, pts)
    hit = (margin <= 0) & (pair >= 0)
    link2 = {int(k) for k in pair[hit] if cm.pair_links[k] == ("link2", "wall")}
    assert len(link2) == 2  # both shapes bind somewhere
    labels = [x for x, _ in scene.legend if x.startswith("colliding: link2 - wall")]
    assert labels == [f"colliding: link2 - wall binds ({sum(int((pair[hit] == k).sum()) for k in link2)} points)"]
    assert sorted(scene._window.tree["meshcat"]["overlays"]["colliding"]) == sorted(
        f"{a}--{b}" for a, b in {cm.pair_links[k] for k in pair[hit]})
    # the serial grid's JSON block counts link 2's two shapes as one pair too
    g = collision_grid(SerialArm(robot), robot, cm, step)
    shapes = [k for k in range(len(cm.pairs)) if cm.pair_links[k] == ("link2", "wall")]
    assert len(shapes) == 2 and all((g.pair == k).any() for k in shapes)
    assert {"links": ["link2", "wall"], "points": int(np.isin(g.pair, shapes).sum())} in g.as_dict()["binding_pairs"]
