"""What `serial_workspace` returns: the measure with its proved bounds, the task-space cells and
their dexterity, the possibly singular boxes, and the points views draw."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from kinematics.errors import InvalidInputError, UnsupportedRobotError
from kinematics.mechanisms.serial.joint_box import Mode as Mode


@dataclass(frozen=True, eq=False)
class CellGrid:
    """A regular grid of task-space cells (side `cell` [m]) from `origin`: cell (i, j[, k]) spans
    origin + (i, j[, k]) * cell to origin + (i + 1, j + 1[, k + 1]) * cell. Coordinates are the
    plane axes (planar), (rho, z) about the base axis (revolved) or x, y, z (spatial)."""

    origin: np.ndarray
    cell: float
    shape: tuple[int, ...]

    def centres(self, index: np.ndarray) -> np.ndarray:
        """Centres [m] of cells given as (K, d) integer indices."""
        return self.origin + (np.asarray(index) + 0.5) * self.cell


def revolve(profile: np.ndarray, origin: np.ndarray, direction: np.ndarray, turns: int) -> np.ndarray:
    """(K * turns, 3) world points [m] of profile points (K, 2) = (rho, z) about the axis through
    `origin` along the unit `direction`, each swept at `turns` evenly spaced azimuths (a point's
    ring consecutive)."""
    a = np.asarray(direction, dtype=float)
    u = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(a, u)
    phi = np.linspace(0, 2 * np.pi, max(1, turns), endpoint=False)
    pts = np.asarray(profile, dtype=float)
    rho, z = pts[:, 0, None], pts[:, 1, None]
    ring = (np.asarray(origin, dtype=float) + rho[..., None] * (np.cos(phi)[None, :, None] * u
                                                                + np.sin(phi)[None, :, None] * v) + z[..., None] * a)
    return ring.reshape(-1, 3)


@dataclass(frozen=True, eq=False)
class SerialWorkspace:
    """Reachable set of a frame's position, with guaranteed bounds and per-cell dexterity.

    Attributes:
        robot, frame: what was measured.
        mode: "planar" (area in the plane axes `axes`, m^2), "revolved" (solid of revolution
            about the first joint's axis, m^3) or "spatial" (m^3).
        axes: world axes of the plane (planar); for revolved, `axis_origin` and `axis_direction`.
        measure: the estimate, (lower + upper) / 2 [m^2 or m^3].
        lower, upper: guaranteed bounds on the measure.
        error_estimate: (upper - lower) / 2, a bound on |measure - true|.
        rtol: the requested relative tolerance; converged: error_estimate <= rtol * measure.
        points_evaluated: configurations at which FK and the Jacobian were evaluated.
        seconds: wall time.
        joints: the degrees of freedom sampled; fixed: those that never move the point.
        lipschitz: bound on |df/dq_i| per sampled joint [m/rad or m/m].
        hessian_bound: M, bound on the second derivative of the position over the joint box.
        grid: the cells; inside: cells certified in W; touched: cells that may meet W (a
            superset of W's cells; inside implies touched).
        yoshikawa, condition_number, smallest_radius: per cell, best over the configurations
            evaluated there (max, min, max); NaN where none was.
        singular_points: (K, d) task coordinates of boxes that may hold a rank-deficient
            Jacobian; singular_radius: (K,) the box's image lies within this distance [m];
            singular_configurations: (K, nv) the boxes' centres (joint values);
            singular_half_widths: (K, nv) their half-widths [rad or m] (0 for the joints not
            sampled: those that never move the point, and a revolved arm's base joint, whose
            every angle the box stands for).
        unsplit: boxes the budget (`max_points`) left unsplit with an image ball above
            `leaf_radius` (0: the budget sufficed; the bounds and the singular balls stay valid,
            only coarser); unsplit_radius: the largest of their balls [m]; leaf_radius: the
            radius below which a box is finished, half a cell [m].
    """

    robot: str
    frame: str
    mode: Mode
    measure: float
    lower: float
    upper: float
    error_estimate: float
    rtol: float
    converged: bool
    points_evaluated: int
    seconds: float
    joints: tuple[str, ...]
    fixed: tuple[str, ...]
    lipschitz: np.ndarray
    hessian_bound: float
    grid: CellGrid
    inside: np.ndarray
    touched: np.ndarray
    yoshikawa: np.ndarray
    condition_number: np.ndarray
    smallest_radius: np.ndarray
    singular_points: np.ndarray
    singular_radius: np.ndarray
    singular_configurations: np.ndarray
    axes: tuple[int, ...] = ()
    axis_origin: np.ndarray | None = None
    axis_direction: np.ndarray | None = None
    levels: tuple[dict[str, float], ...] = field(default=())
    plane_offset: float = 0.0
    singular_half_widths: np.ndarray | None = None
    unsplit: int = 0
    unsplit_radius: float = 0.0
    leaf_radius: float = 0.0

    @property
    def planar(self) -> bool:
        """The measure is an area in the plane `axes`."""
        return self.mode == "planar"

    def world_points(self, which: Literal["inside", "touched", "band", "singular"] = "inside",
                     turns: int = 48) -> np.ndarray:
        """(K, 3) world points [m] for views: centres of the certified cells ("inside"), of the
        cells that may meet W ("touched"), of the uncertain band between them ("band"), or the
        images of the possibly singular boxes ("singular"). A revolved profile is swept about the
        base axis at `turns` angles; a planar arm's points lie in its plane (at `plane_offset`)."""
        if which == "singular":
            pts = self.singular_points
        else:
            masks = {"inside": self.inside, "touched": self.touched, "band": self.touched & ~self.inside}
            if which not in masks:
                raise InvalidInputError("which", f"expected one of inside, touched, band, singular; got {which!r}")
            pts = self.grid.centres(np.argwhere(masks[which]))
        if self.mode == "spatial":
            return np.asarray(pts, dtype=float).reshape(-1, 3)
        if self.mode == "planar":
            out = np.full((len(pts), 3), self.plane_offset)
            out[:, list(self.axes)] = pts
            return out
        if self.axis_direction is None or self.axis_origin is None:
            raise UnsupportedRobotError(self.robot, f"a {self.mode!r} workspace has no revolution axis")
        return revolve(pts, self.axis_origin, self.axis_direction, turns)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready summary with the issue's stable keys (volume_m3 or area_m2,
        error_estimate, points_evaluated, seconds)."""
        key = "area_m2" if self.planar else "volume_m3"
        out: dict[str, Any] = {
            "robot": self.robot,
            "frame": self.frame,
            "mode": self.mode,
            key: self.measure,
            "error_estimate": self.error_estimate,
            "bounds": [self.lower, self.upper],
            "rtol": self.rtol,
            "converged": self.converged,
            "points_evaluated": self.points_evaluated,
            "seconds": self.seconds,
            "cell_m": self.grid.cell,
            "joints": list(self.joints),
            "fixed_joints": list(self.fixed),
            "singular_boxes": len(self.singular_radius),
            "unsplit_boxes": self.unsplit,
            "unsplit_radius_m": self.unsplit_radius,
            "leaf_radius_m": self.leaf_radius,
            "levels": list(self.levels),
        }
        if self.axis_direction is not None and self.axis_origin is not None:
            out["axis"] = {"origin": self.axis_origin.tolist(), "direction": self.axis_direction.tolist()}
        if self.axes:
            out["plane_axes"] = list(self.axes)
        return out

