"""sweep with collisions (issue 30 item 3): each design's collision-free volume, from the URDF the
generator writes for it, against a Monte Carlo estimate that checks coal at configurations built
point by point (`joint_values`), not through the compiled closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.analyses import sweep as sw
from kinematics.generic.collision import CollisionModel
from kinematics.generic.obstacles import load_obstacles
from kinematics.mechanisms.p2us import urdf as p2us_urdf
from kinematics.mechanisms.p2us.closed_form import MODES, P2USParams, ik
from kinematics.mechanisms.p2us.mechanism import P2US
from kinematics.mechanisms.p2us.scan import bounding_box
from kinematics.mechanisms.three_limb.urdf import CollisionSizes
from kinematics.model.robot import load_robot

FLOOR = "obstacles:\n  - {name: floor, halfspace: [0, 0, 1, -0.50]}\n"


@pytest.fixture(scope="module")
def client():
    from distributed import Client

    with Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=None) as c:
        yield c


def _monte_carlo(params: P2USParams, sizes: CollisionSizes, obstacles, n: int, rng, tmp_path) -> tuple[float, float]:
    """(volume, standard error) [m^3] of the points where some working mode is within every limit
    (NumPy IK) and its configuration (`joint_values`, `robot.configuration`) has no pair with a
    negative coal distance."""
    urdf, _ = p2us_urdf.write(params, tmp_path / "mc.urdf", sizes=sizes)
    robot = load_robot(urdf)
    cm = CollisionModel.from_robot(robot, obstacles=obstacles, self_collisions=False)
    mech = P2US(params)
    lo, hi = bounding_box(params)
    pts = lo + (hi - lo) * rng.random((n, 3))
    ok = ik(params, pts).within_limits
    free = np.zeros(n, bool)
    for i in np.flatnonzero(ok.any(axis=1)):
        for m in np.flatnonzero(ok[i]):
            values = mech.joint_values(pts[i], MODES[m])
            q = robot.configuration([values[name] for name in robot.joint_names])
            if cm.distances(q[None, :])[0].min() > 0:
                free[i] = True
                break
    box = float(np.prod(hi - lo))
    f = free.mean()
    return box * f, box * np.sqrt(f * (1 - f) / n)


def test_sweep_reports_each_designs_collision_free_volume(client, tmp_path, rng):
    """Two designs (b = 0.30, 0.34 m) above a floor z >= -0.50 m (obstacles only: the generated
    rods and platform against a half-space): the collision-free volume column agrees with Monte
    Carlo (4 standard errors and 3 of the row's own estimates), is below the
    kinematic volume (the floor binds), and follows the swept parameter."""
    (tmp_path / "floor.yaml").write_text(FLOOR)
    sizes = CollisionSizes(rod_radius=0.008, arm_radius=0.01, plate_thickness=0.02, plate_overhang=0.03,
                           platform_overhang=0.03)
    opts = {"sizes": {"rod_radius": 0.008, "arm_radius": 0.01, "plate_thickness": 0.02, "plate_overhang": 0.03,
                      "platform_overhang": 0.03}, "self": False, "obstacles": str(tmp_path / "floor.yaml")}
    rows = sw.run([sw.Axis.parse("b=0.30:0.34:2")], step=0.05, rtol=1e-2, client=client, collisions=opts)
    assert sw.columns_of(rows)[-2:] == sw.COLLISION_COLUMNS
    obstacles = load_obstacles(tmp_path / "floor.yaml")
    for row in rows:
        free = row["collision_free_volume_m3"]
        assert 0 < free < row["volume_m3"] - 2 * row["collision_free_error_m3"]
        mc, se = _monte_carlo(P2USParams().replace(b=row["b"]), sizes, obstacles, 40_000, rng, tmp_path)
        # 4 standard errors (about 1e-3 m^3 here, less than the floor removes) and 3 error estimates
        assert abs(free - mc) <= 4 * se + 3 * row["collision_free_error_m3"]
    assert rows[0]["collision_free_volume_m3"] != rows[1]["collision_free_volume_m3"]
    assert "collision_free_volume_m3" in sw.to_csv(rows).splitlines()[0]


def test_synthesis_cube_objective_is_collision_free(tmp_path):
    """synthesize's usable-cube objective with obstacles: p2us-results' design above the floor
    z >= -0.62 m gives the cube of the hand field min(u, z - (-0.62 + d + platform overhang)) (the
    platform's sphere is the lowest body; the search reads only signs), smaller than without it."""
    from kinematics.analyses import synthesis as syn
    from kinematics.analyses.collisions import design_options
    from kinematics.analyses.usable import largest_shape, usable_field
    from kinematics.mechanisms import mechanism_of

    (tmp_path / "floor.yaml").write_text("obstacles:\n  - {name: floor, halfspace: [0, 0, 1, -0.62]}\n")
    robot = load_robot("p2us-results")
    mech = mechanism_of(robot)
    opts = design_options(robot, False, str(tmp_path / "floor.yaml"))
    settings = syn.Settings(cube_cells=16, gci_samples=256, gci_replicates=2, collisions=opts)
    got = syn.evaluate("p2us", mech.params, {}, settings)
    free = syn.evaluate("p2us", mech.params, {}, syn.Settings(cube_cells=16, gci_samples=256, gci_replicates=2))
    lo, hi = mech.bounding_box("all")
    step = float(np.max(hi - lo)) / 16
    top = -0.62 + mech.params.d + opts["sizes"]["platform_overhang"]
    u = usable_field(mech, "---")
    hand = largest_shape(lambda p: np.minimum(u(p), p[:, 2] - top), lo, hi, "cube", step=step, search=False)
    assert got["cube_edge_m"] == pytest.approx(hand.size[0], abs=1e-12)
    assert got["cube_edge_m"] < free["cube_edge_m"] - step / 4
    assert got["gci"] == free["gci"]  # the GCI stays kinematic
