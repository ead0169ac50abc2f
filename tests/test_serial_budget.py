"""The serial cell engine's cost stays within its budget: level 0 fits `max_points`, cells are
marked by rows and balls that can add nothing are dropped (exactly the cells of the balls where
it matters), and a budget too small for the arm is reported (the panda's singular scan)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from kinematics.analyses.serial_workspace import kernels, serial_workspace
from kinematics.generic.batched import batched_fk, configurations
from kinematics.model.robot import load_robot

from .test_cli import run, run_json

MODELS = Path(__file__).parent / "models"


def _cells_by_geometry(y, rad, origin, h, d, shape, inner):
    """The cells wholly inside (inner) or meeting the closed balls, one cell at a time: a cell
    [a, a + h] is inside B(c, r) when its farthest corner is, and meets it when its nearest point
    is within r (independent of the kernel's row spans)."""
    grid = np.zeros(shape, np.uint8)
    idx = np.indices(shape[:d]).reshape(d, -1).T
    lo = origin[:d] + idx * h
    for c, r in zip(y, rad, strict=True):
        a, b = lo - c[:d], lo - c[:d] + h
        if inner:
            ok = (np.sqrt((np.maximum(np.abs(a), np.abs(b)) ** 2).sum(axis=1)) <= r) & (r > 0)
        else:
            ok = (np.sqrt((np.maximum(0.0, np.maximum(a, -b)) ** 2).sum(axis=1)) <= r) & (r >= 0)
        grid[tuple(idx[ok].T) if d == 3 else (idx[ok, 0], idx[ok, 1], 0)] = 1
    return grid


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("inner", [False, True])
@pytest.mark.parametrize("batched", [False, True])
def test_marking_is_the_balls_cells(rng, monkeypatch, d, inner, batched):
    """Row spans, with or without the batches that drop balls adding nothing, set exactly the
    cells of the balls within `care` (the reach), and no cell outside the balls; a zero radius
    still touches its own cell, a negative one nothing. Cells already set stay set."""
    if batched:  # every ball its own batch: the drop test runs after each
        monkeypatch.setattr(kernels, "BATCH_ROWS", 1e-9)
        monkeypatch.setattr(kernels, "MIN_BATCH_ROWS", 1)
    shape = (17, 23, 19) if d == 3 else (31, 27, 1)
    h, origin = 0.1, np.array([-0.3, 0.2, -0.5])
    y = origin + rng.uniform(-0.3, 2.5, (80, 3))
    y[:, d:] = 0.0
    rad = rng.uniform(0.0, 0.6, 80)
    rad[:4] = [0.0, -1.0, 1.3, 0.9]  # a point, nothing, two balls much larger than a cell
    before = (rng.random(shape) < 0.02).astype(np.uint8)
    exact = _cells_by_geometry(y, rad, origin, h, d, shape, inner) | before
    grid = before.copy()
    kernels._mark(y, rad, origin, h, d, grid, inner, None)
    assert (grid == exact).all()
    care = _cells_by_geometry(origin[None, :] + [1.0, 1.2, 0.9], np.array([0.7]), origin, h, d, shape, False)
    grid = before.copy()
    kernels._mark(y, rad, origin, h, d, grid, inner, care)
    assert (grid[care == 1] == exact[care == 1]).all() and (grid <= exact).all()


def test_marking_drops_balls_that_add_nothing(rng, monkeypatch):
    """20,000 balls each holding the whole reach (as the panda's budget leaves do: radii of
    40-110 cells, ~10^12 cell visits one by one), and a cell of the reach's grid no ball meets
    (the marking never runs out of open cells): after the first batch the distance transform
    shows no ball can add a cell, so at most one batch of balls is marked."""
    marked = []
    rows = kernels._rows

    def counting(y, rad, origin, h, d, diff, inner, which):
        marked.append(len(which))
        rows(y, rad, origin, h, d, diff, inner, which)

    monkeypatch.setattr(kernels, "_rows", counting)
    shape, h, origin = (150, 150, 150), 0.0146, np.full(3, -1.1)
    centre = np.zeros(3)
    y = centre + rng.uniform(-0.05, 0.05, (20_000, 3))
    rad = rng.uniform(0.9, 1.0, 20_000)  # |y - centre| < 0.09 m: every ball holds the 0.8 m reach
    care = np.zeros(shape, np.uint8)
    kernels._mark(centre[None, :], np.array([0.8]), origin, h, 3, care, False, None)
    care[0, 0, 0] = 1  # 1.9 m from the centre: beyond every ball
    marked.clear()
    grid = np.zeros(shape, np.uint8)
    kernels._mark(y, rad, origin, h, 3, grid, False, care)
    assert (grid[care == 1] == 1).sum() == care.sum() - 1 and grid[0, 0, 0] == 0
    # a batch is max(BATCH_ROWS x cells, MIN_BATCH_ROWS) rows, a ball at least (2 x 0.9 / h)^2
    per_batch = max(kernels.BATCH_ROWS * grid.size, kernels.MIN_BATCH_ROWS) / (2 * 0.9 / h) ** 2
    assert sum(marked) <= per_batch + 1 < 2000


def test_budget_holds_from_level_zero(rng):
    """The UR5's first partition alone is 7,728 boxes: at a budget of 1,000 it is coarsened, the
    budget holds, the unsplit boxes are counted with their largest ball, and the upper set still
    covers random reached points."""
    robot = load_robot("ur5")
    w = serial_workspace(robot, resolution=64, max_points=1000)
    assert 0 < w.points_evaluated <= 1000
    assert w.unsplit > 0 and w.unsplit_radius > w.leaf_radius == pytest.approx(0.5 * w.grid.cell, rel=1e-12)
    values = rng.uniform(-np.pi, np.pi, (5000, 6))
    p = batched_fk(robot, configurations(robot, values)).position - w.axis_origin
    z = p @ w.axis_direction
    rho = np.linalg.norm(p - z[:, None] * w.axis_direction, axis=1)
    cells = np.floor((np.stack([rho, z], axis=1) - w.grid.origin) / w.grid.cell).astype(int)
    assert w.touched[tuple(cells.T)].all()
    assert w.as_dict()["unsplit_boxes"] == w.unsplit


def test_singularities_budget_report(capsys):
    """The panda (six joints move its tool point, the base a part turn: a spatial scan) within
    a budget of 20,000 configurations: the budget holds and the report says it ran out, how many
    boxes it left unsplit and how large their balls are; a small arm's default budget suffices."""
    code, d, _ = run_json(capsys, "singularities", "panda", "--max-points", "20000", "--resolution", "16")
    assert code == 0 and d["mode"] == "spatial" and d["points_evaluated"] <= 20_000
    assert d["budget_exhausted"] and 0 < d["unsplit_boxes"] <= d["points_evaluated"]
    assert d["unsplit_radius_m"] > d["leaf_radius_m"] > 0
    code, out, _ = run(capsys, "singularities", str(MODELS / "arm3r_revolved.urdf"), "--resolution", "100")
    assert code == 0 and "budget" in out and "sufficed" in out
