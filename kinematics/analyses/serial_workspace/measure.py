"""`serial_workspace`, the measurement (method in the package docstring): level 0 is evaluated
and sizes the cell grid; then, level by level, cells are certified (Graves' balls, the components
the critical boxes' balls leave free), each box is settled, left as a leaf or split, and the cells
the leaves' balls touch are marked; the bounds are the measures of the two cell sets."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from kinematics.analyses.serial_workspace.boxes import LEAF, evaluate, level_zero, split, split_mask
from kinematics.analyses.serial_workspace.kernels import (
    aggregate,
    cell_measure,
    mark_touching,
    mark_within,
    meets_ball,
)
from kinematics.analyses.serial_workspace.result import CellGrid, SerialWorkspace
from kinematics.errors import InvalidInputError, UnsupportedRobotError
from kinematics.generic.batched import BatchedKinematics, configurations
from kinematics.mechanisms.serial.joint_box import Setup, on_face, room, setup
from kinematics.model.robot import Robot


def serial_workspace(
    robot: Robot,
    frame: str | None = None,
    *,
    rtol: float = 0.02,
    cell: float | None = None,
    resolution: int | None = None,
    max_points: int = 20_000_000,
    progress: bool = False,
) -> SerialWorkspace:
    """Reachable set of `frame`'s origin (default: the tool) within the joint limits.

    Args:
        robot: a loaded serial robot (`kinematics.model.robot.load_robot`).
        frame: the frame whose position is measured.
        rtol: the accuracy asked for: `converged` says whether error_estimate <= rtol * measure.
            (The refinement itself is set by the cell: the error estimate falls linearly with h.)
        cell: task-space cell side h [m]; default: the bounding box's largest side / resolution.
        resolution: cells along that side (default 400 for a plane or profile, 128 in space).
        max_points: budget of configurations; when it runs out the remaining boxes are counted
            with their (larger) balls, so the bounds stay valid but widen.
        progress: show a bar on stderr (for the CLI on a terminal).

    Returns:
        A `SerialWorkspace` with guaranteed bounds (see the package docstring).

    Raises:
        UnsupportedRobotError: closed-loop robots, joints the batched kinematics cannot compile,
            unbounded prismatic joints, a frame no joint moves.
        InvalidInputError: rtol, cell, resolution or max_points out of range.
    """
    t0 = time.perf_counter()
    _check_arguments(robot, rtol, cell, resolution, max_points)
    kin = BatchedKinematics.from_robot(robot, frame)
    s = setup(robot, kin)
    d = 2 if s.mode in ("planar", "revolved") else 3
    centre, half = level_zero(s, max_points)
    evaluated = evaluate(robot, kin, s, centre, half)
    plane_offset = _plane_offset(robot, kin, s, centre)
    y, eps = evaluated[0], evaluated[4]
    cells = Cells.cover(s, d, y, eps, cell, resolution)
    run = _refine(robot, kin, s, cells, centre, half, evaluated, max_points, progress)
    cells.fill_components(np.zeros((0, 3)), np.zeros(0))
    cells.touched &= cells.reach  # W lies in the reach ball
    cells.touched |= cells.inside
    return _result(robot, kin, s, cells, run, rtol, plane_offset, t0)


def _check_arguments(robot: Robot, rtol: float, cell: float | None, resolution: int | None, max_points: int) -> None:
    if robot.loops is not None:
        raise UnsupportedRobotError(robot.name, "closed-loop robot: the serial workspace needs an open chain")
    if not (rtol > 0 and math.isfinite(rtol)):
        raise InvalidInputError("rtol", f"must be positive, got {rtol}")
    if cell is not None and not (cell > 0 and math.isfinite(cell)):
        raise InvalidInputError("cell", f"must be a positive length [m], got {cell}")
    if resolution is not None and resolution < 4:
        raise InvalidInputError("resolution", f"must be at least 4 cells, got {resolution}")
    if max_points < 1000:
        raise InvalidInputError("max_points", f"must be at least 1000, got {max_points}")


def _plane_offset(robot: Robot, kin: BatchedKinematics, s: Setup, centre: np.ndarray) -> float:
    """A planar arm's constant coordinate along the plane's normal, at the first box's centre
    (0 for the other modes)."""
    if s.mode != "planar":
        return 0.0
    normal = ({0, 1, 2} - set(s.axes)).pop()
    values = s.base.copy()
    values[s.active] = centre[0]
    return float(kin.fk(configurations(robot, values[None, :])).position[0, normal])


@dataclass(eq=False)
class Cells:
    """The task-space cells while the measurement runs (all (nx, ny, nz) grids, nz = 1 for d = 2):
    certified in W (`inside`), met by a leaf's ball (`touched`), met by the ball of a leaf that
    may map onto the boundary (`boundary_leaves`), the per-cell dexterity (Yoshikawa `gw`,
    condition number `gc`, smallest radius `gr`; NaN where no configuration was evaluated) and
    each cell's measure (`weight`), and the cells meeting the reach ball, where W lies (`reach`:
    the marks outside it may be incomplete, `kernels.mark_touching`)."""

    d: int
    h: float
    origin: np.ndarray  # (d,)
    origin3: np.ndarray  # (3,), zero past d
    shape3: tuple[int, ...]
    inside: np.ndarray
    touched: np.ndarray
    boundary_leaves: np.ndarray
    gw: np.ndarray
    gc: np.ndarray
    gr: np.ndarray
    weight: np.ndarray
    reach: np.ndarray

    @classmethod
    def cover(cls, s: Setup, d: int, y: np.ndarray, eps: np.ndarray, cell: float | None,
              resolution: int | None) -> Cells:
        """Empty cell sets over the box that holds W, from level 0's points y and balls eps; the
        cell side from `cell`, or the reached extent / `resolution`."""
        # W lies in the level-0 balls and in the reach ball: the grid covers their common box.
        lo_box = np.maximum((y - eps[:, None]).min(axis=0), s.reach_centre - s.reach)
        hi_box = np.minimum((y + eps[:, None]).max(axis=0), s.reach_centre + s.reach)
        if s.mode == "revolved":
            lo_box[0] = 0.0
        side = float((y.max(axis=0) - y.min(axis=0)).max())  # the reached extent sets the cell
        if cell is None:
            res = resolution if resolution is not None else (400 if d == 2 else 128)
            h = side / res
        else:
            h = float(cell)
        origin = lo_box - h if s.mode != "revolved" else np.array([0.0, lo_box[1] - h])
        shape3 = tuple(math.ceil((hi_box[a] + h - origin[a]) / h) + 1 if a < d else 1 for a in range(3))
        if np.prod(shape3) > 400_000_000:
            raise InvalidInputError("cell", f"{h:.3g} m makes {np.prod(shape3):.3g} cells; choose a larger cell")
        origin3 = np.zeros(3)
        origin3[:d] = origin
        return cls(d=d, h=h, origin=origin, origin3=origin3, shape3=shape3,
                   inside=np.zeros(shape3, np.uint8), touched=np.zeros(shape3, np.uint8),
                   boundary_leaves=np.zeros(shape3, np.uint8),  # balls of final boxes that may map onto the boundary
                   gw=np.full(shape3, np.nan), gc=np.full(shape3, np.nan), gr=np.full(shape3, np.nan),
                   weight=cell_measure(s.mode, origin, h, shape3),
                   reach=meets_ball(origin, h, shape3, d, s.reach_centre, s.reach))

    def fill_components(self, current_y3: np.ndarray, current_eps: np.ndarray) -> None:
        """Certify the components of the cells no critical ball meets that hold a reached point."""
        from scipy.ndimage import label

        # dW lies in f(limit faces) u f(rank-deficient set): inside the balls of the boxes that
        # may hold such points. A face-connected component of the other cells is disjoint from dW,
        # hence wholly in W or wholly out; it is in W if it holds a reached point.
        cover = self.boundary_leaves | (self.reach == 0)  # no cell beyond the reach ball is in W
        mark_touching(current_y3, current_eps, self.origin3, self.h, self.d, cover, self.reach)
        free = cover == 0
        labels, _ = label(free if self.d == 3 else free[:, :, 0])
        if self.d == 2:
            labels = labels[:, :, None]
        seeds = np.unique(labels[(self.inside == 1) | ~np.isnan(self.gw)])
        seeds = seeds[seeds > 0]
        self.inside[np.isin(labels, seeds)] = 1

    def measure(self, cells: np.ndarray) -> float:
        """The measure of a set of cells (a 0/1 grid)."""
        return float((self.weight * cells).sum())


@dataclass(eq=False)
class _Run:
    """What the refinement gathers besides the cells: configurations evaluated, a summary per
    level, the boxes the budget left unsplit (how many, their largest ball) and the possibly
    singular boxes (task points, ball radii, centres in joint values and half-widths)."""

    points: int = 0
    unsplit: int = 0
    unsplit_radius: float = 0.0
    levels: list[dict[str, float]] = field(default_factory=list)
    sing_pts: list[np.ndarray] = field(default_factory=list)
    sing_rad: list[np.ndarray] = field(default_factory=list)
    sing_cfg: list[np.ndarray] = field(default_factory=list)
    sing_half: list[np.ndarray] = field(default_factory=list)


def _refine(robot: Robot, kin: BatchedKinematics, s: Setup, cells: Cells, centre: np.ndarray, half: np.ndarray,
            evaluated: tuple[np.ndarray, ...], max_points: int, progress: bool) -> _Run:
    """Level after level from the evaluated level 0, until no box is left to split."""
    run = _Run()
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=max_points, desc="workspace", unit="cfg", unit_scale=True, delay=1.0, leave=False)
    try:
        while True:
            run.points += len(centre)
            if bar is not None:
                bar.update(len(centre))
            children = _level(cells, s, run, centre, half, evaluated, max_points)
            if children is None:
                break
            centre, half = children
            evaluated = evaluate(robot, kin, s, centre, half)
    finally:
        if bar is not None:
            bar.close()
    return run


def _level(cells: Cells, s: Setup, run: _Run, centre: np.ndarray, half: np.ndarray,
           evaluated: tuple[np.ndarray, ...], max_points: int) -> tuple[np.ndarray, np.ndarray] | None:
    """One level: certify cells, settle each box, leave it as a leaf or split it, mark the cells
    the leaves' balls touch. Returns the children to evaluate next (None: the last level)."""
    y, eps, norms = evaluated[0], evaluated[4], evaluated[5]
    d, h = cells.d, cells.h
    y3 = np.zeros((len(y), 3))
    y3[:, :d] = y
    idx, maybe_singular, critical = _certify(cells, s, centre, half, y3, evaluated)
    settled = _settled(cells, idx, eps)
    leaf, children = _leaves_and_children(s, centre, half, norms, eps, settled, max_points - run.points, h)
    final = settled | leaf
    unsplit = leaf & (eps > LEAF * h)  # left with a ball above a leaf's: the budget ran out
    if unsplit.any():
        run.unsplit += int(unsplit.sum())
        run.unsplit_radius = max(run.unsplit_radius, float(eps[unsplit].max()))
    maybe_singular &= final
    mark_touching(y3[leaf & critical], eps[leaf & critical], cells.origin3, h, d, cells.boundary_leaves, cells.reach)
    if maybe_singular.any():
        run.sing_pts.append(y[maybe_singular])
        run.sing_rad.append(eps[maybe_singular])
        cfg = np.repeat(s.base[None, :], int(maybe_singular.sum()), axis=0)
        cfg[:, s.active] = centre[maybe_singular]
        run.sing_cfg.append(cfg)
        widths = np.zeros_like(cfg)
        widths[:, s.active] = half[maybe_singular]
        run.sing_half.append(widths)
    mark_touching(y3[leaf], eps[leaf], cells.origin3, h, d, cells.touched, cells.reach)
    run.levels.append({"boxes": float(len(centre)), "settled": float(settled.sum()), "leaves": float(leaf.sum()),
                       "max_eps_m": float(eps.max()),
                       "lower": cells.measure(cells.inside),
                       "upper_so_far": cells.measure(cells.touched | cells.inside)})
    return children


def _certify(cells: Cells, s: Setup, centre: np.ndarray, half: np.ndarray, y3: np.ndarray,
             evaluated: tuple[np.ndarray, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mark the cells Graves' balls certify, aggregate the dexterity per cell, and certify the
    components the critical boxes' balls leave free. Returns each box's cell index, the boxes
    that may hold a rank-deficient Jacobian, and those or the boxes on a limit face (critical)."""
    _, sig_min, sig_max, yosh, eps, _ = evaluated
    d, h = cells.d, cells.h
    # Graves: the largest certified task ball at each centre.
    r_lim = room(centre, s)
    r = np.minimum(sig_min / (2 * s.M), r_lim) if s.M > 0 else np.where(np.isfinite(r_lim), r_lim, 1.0)
    ball = (sig_min - s.M * r) * r
    # Cap the marking to what settling this box needs (keeps the work ~ one cover per level).
    mark_within(y3, np.minimum(ball, eps + 2 * h * math.sqrt(d)), cells.origin3, h, d, cells.inside, cells.reach)
    idx = np.clip(np.floor((y3 - cells.origin3) / h).astype(np.int64), 0, np.array(cells.shape3) - 1)
    idx[:, d:] = 0
    with np.errstate(divide="ignore"):
        cond = np.where(sig_min > 0, sig_max / np.where(sig_min > 0, sig_min, 1.0), np.inf)
    aggregate(idx, yosh, cond, sig_min, cells.gw, cells.gc, cells.gr)
    # Boxes that may hold a limit-face or rank-deficient configuration (sigma_min is
    # Lipschitz in q: sigma_min(J(s)) > sum_i d_i |dJ/dq_i| rules out a singular point in the box).
    maybe_singular = sig_min <= half @ s.Bcol  # |J(q) - J(s)| <= sum_i d_i |dJ/dq_i|
    critical = maybe_singular | on_face(centre, half, s)
    cells.fill_components(y3[critical], eps[critical])
    return idx, maybe_singular, critical


def _settled(cells: Cells, idx: np.ndarray, eps: np.ndarray) -> np.ndarray:
    """Which boxes are settled (image ball inside the certified cells)?"""
    from scipy.ndimage import distance_transform_edt

    d, h, inside = cells.d, cells.h, cells.inside
    pad = np.pad(inside.astype(bool), 1)
    dist = distance_transform_edt(pad)[1:-1, 1:-1, 1:-1] if d == 3 else \
        distance_transform_edt(pad[:, :, 1])[1:-1, 1:-1][:, :, None]
    room_task = dist[idx[:, 0], idx[:, 1], idx[:, 2]] * h - h * math.sqrt(d)
    return (inside[idx[:, 0], idx[:, 1], idx[:, 2]] == 1) & (eps <= room_task)


def _leaves_and_children(s: Setup, centre: np.ndarray, half: np.ndarray, norms: np.ndarray, eps: np.ndarray,
                         settled: np.ndarray, budget: int,
                         h: float) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray] | None]:
    """The leaves (unsettled boxes with a small enough ball, and those the budget of `budget`
    configurations cannot split) and the children of the others (None: none)."""
    leaf = ~settled & (eps <= LEAF * h)
    rest = ~settled & ~leaf
    children = None
    if rest.any():
        # Within the budget, split the boxes with the largest balls first; the others
        # become leaves counted by their balls (the bounds stay valid, only wider).
        mask = split_mask(half[rest], norms[rest], s.B)
        count = 2 ** mask.sum(axis=1)
        order = np.argsort(-eps[rest], kind="stable")
        fits = np.cumsum(count[order]) <= budget
        chosen = np.flatnonzero(rest)[order[fits]]
        leaf |= rest
        leaf[chosen] = False
        if len(chosen):
            children = split(centre[chosen], half[chosen], split_mask(half[chosen], norms[chosen], s.B))
    return leaf, children


def _result(robot: Robot, kin: BatchedKinematics, s: Setup, cells: Cells, run: _Run, rtol: float,
            plane_offset: float, t0: float) -> SerialWorkspace:
    """The bounds (measures of the certified and the touched cells), the per-cell grids cut to d
    axes, and the singular boxes, as a `SerialWorkspace`."""
    d = cells.d
    lower = cells.measure(cells.inside)
    upper = cells.measure(cells.touched)
    measure = 0.5 * (lower + upper)
    err = 0.5 * (upper - lower)
    sl = (slice(None), slice(None), 0) if d == 2 else (slice(None),) * 3
    return SerialWorkspace(
        robot=robot.name,
        frame=kin.frame,
        mode=s.mode,
        measure=measure,
        lower=lower,
        upper=upper,
        error_estimate=err,
        rtol=rtol,
        converged=bool(err <= rtol * measure),
        points_evaluated=run.points,
        seconds=time.perf_counter() - t0,
        joints=tuple(robot.dofs[i].name for i in s.active),
        fixed=s.fixed,
        lipschitz=s.L.copy(),
        hessian_bound=s.M,
        grid=CellGrid(origin=cells.origin.copy(), cell=cells.h, shape=tuple(cells.shape3[:d])),
        inside=cells.inside[sl].astype(bool),
        touched=cells.touched[sl].astype(bool),
        yoshikawa=cells.gw[sl],
        condition_number=cells.gc[sl],
        smallest_radius=cells.gr[sl],
        singular_points=np.concatenate(run.sing_pts) if run.sing_pts else np.zeros((0, d)),
        singular_radius=np.concatenate(run.sing_rad) if run.sing_rad else np.zeros(0),
        singular_configurations=np.concatenate(run.sing_cfg) if run.sing_cfg else np.zeros((0, robot.nv)),
        axes=s.axes,
        axis_origin=s.axis_origin,
        axis_direction=s.axis_direction,
        levels=tuple(run.levels),
        plane_offset=plane_offset,
        singular_half_widths=np.concatenate(run.sing_half) if run.sing_half else np.zeros((0, robot.nv)),
        unsplit=run.unsplit,
        unsplit_radius=run.unsplit_radius,
        leaf_radius=LEAF * cells.h,
    )
