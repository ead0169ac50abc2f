"""The compiled model of a closed-loop mechanism that the batched solver works on (`LoopModel`, the
base of `LoopBatch`): the tree and closure arrays packed for the kernels of `compiled`, the
residual rows and their sparsity, and the kernels' entry points (`newton`, `evaluate`).

The rows are, in order: every closure (3 rows for a `point` closure, 6 for a `6d` one), the
end effector's orientation held at R_0 (3 rows: translational mechanisms, or a rotation asked
for), the task position (d rows); `compiled` gives the equations.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin

from kinematics import jit
from kinematics.errors import UnsupportedRobotError
from kinematics.generic.loop_batch.compiled import PRISMATIC, REVOLUTE, TOL, eval_kernel, lm_kernel, pack
from kinematics.inputs import task_points
from kinematics.model.robot import Robot

if TYPE_CHECKING:
    from kinematics.generic.loop_batch.structure import Block
    from kinematics.generic.loop_batch.warm import WarmCache


def row_pattern(anc: np.ndarray, ctype: np.ndarray, cf1: np.ndarray, cf2: np.ndarray, ee: int,
                 task: int) -> np.ndarray:
    """(m, n) bool: the unknowns each residual row can depend on, from the frames' ancestors."""
    out = []
    for k, t in enumerate(ctype):
        out += [anc[cf1[k]] | anc[cf2[k]]] * (3 if t == 0 else 6)
    out += [anc[ee]] * task
    return np.array(out, dtype=bool).reshape(len(out), anc.shape[1])


def sparsity(pattern: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The kernel's per-row column lists (padded with -1) and their lengths."""
    cols = [np.flatnonzero(row) for row in pattern]
    width = max([len(c) for c in cols] + [1])
    nzn = np.array([len(c) for c in cols], dtype=np.int64)
    nzc = np.array([np.pad(c, (0, width - len(c)), constant_values=-1) for c in cols], dtype=np.int64)
    return nzc.reshape(len(cols), width), nzn


@dataclass(eq=False)
class LoopModel:
    """The dataclass under `LoopBatch`: its fields and the compiled model.

    Attributes: robot; task_axes, oriented and scale (the task and the model's length, chosen by
    `LoopBatch.from_robot`; oriented: the end effector's orientation rows are solved, held at R_0,
    because the actuators never turn it (`translational`) or, `held`, because a rotation was asked
    for); labels and atlas (the branches, `atlas`); blocks (`structure`); restarts and solver
    (`LoopBatch.ik`); spheres, the block solver solves spherical triples behind 6D closures in
    closed form (`spheres`); frames, the closure and end-effector frames in the
    kernels' order; _g, the model tuple (`pack` flattens it for the kernels);
    _m, the number of residual rows; _nzc, _nzn, each row's structurally non-zero columns; _centre,
    the middle of each joint's limits (0 without); _reference, the sidecar's closed reference
    configuration; _anchor, the end effector's task coordinates there; _warm, the warm-start cache.
    """

    robot: Robot
    task_axes: tuple[int, ...]
    oriented: bool
    scale: float
    labels: tuple[tuple[int, ...], ...] = ()
    atlas: np.ndarray = field(default_factory=lambda: np.empty((0, 0)))
    blocks: tuple[Block, ...] = ()
    restarts: int = 8
    solver: str = "blocks"
    held: bool = False
    spheres: bool = True
    frames: tuple[str, ...] = ()
    _g: tuple[Any, ...] = ()
    _m: int = 0
    _nzc: np.ndarray = field(default_factory=lambda: np.empty((0, 0), dtype=np.int64))
    _nzn: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    _centre: np.ndarray = field(default_factory=lambda: np.empty(0))
    _reference: np.ndarray = field(default_factory=lambda: np.empty(0))
    _anchor: np.ndarray = field(default_factory=lambda: np.empty(0))
    _warm: WarmCache | None = None

    def _compile(self, q: np.ndarray) -> None:
        robot, model, spec = self.robot, self.robot.model, self.robot.loops
        if spec is None:
            raise UnsupportedRobotError(robot.name, "the batched closed-loop solver needs a loop sidecar")
        n = model.njoints - 1
        parent = np.array([int(model.parents[j]) - 1 for j in range(1, n + 1)], dtype=np.int64)
        kind, axes = [], []
        data = model.createData()
        pin.forwardKinematics(model, data, pin.neutral(model))
        for j in range(1, n + 1):
            S = np.asarray(data.joints[j].S).reshape(6)
            prismatic = float(np.linalg.norm(S[:3])) > 0.5
            a = S[:3] if prismatic else S[3:]
            kind.append(PRISMATIC if prismatic else REVOLUTE)
            axes.append(a / np.linalg.norm(a))
        jR = np.array([model.jointPlacements[j].rotation for j in range(1, n + 1)], dtype=float).reshape(n, 3, 3)
        jt = np.array([model.jointPlacements[j].translation for j in range(1, n + 1)], dtype=float).reshape(n, 3)
        frames = []
        for c in spec.closures:
            frames += [c.frame1, c.frame2]
        frames.append(spec.end_effector)
        frames = list(dict.fromkeys(frames))
        self.frames = tuple(frames)
        fids = [robot.frame_id(f) for f in frames]
        fparent = np.array([int(model.frames[f].parentJoint) - 1 for f in fids], dtype=np.int64)
        fR = np.array([model.frames[f].placement.rotation for f in fids], dtype=float).reshape(-1, 3, 3)
        ft = np.array([model.frames[f].placement.translation for f in fids], dtype=float).reshape(-1, 3)
        anc = np.zeros((len(fids), n), dtype=np.bool_)
        for i, fp in enumerate(fparent):
            j = int(fp)
            while j >= 0:
                anc[i, j] = True
                j = int(parent[j])
        ctype = np.array([0 if c.type == "point" else 1 for c in spec.closures], dtype=np.int64)
        cf1 = np.array([frames.index(c.frame1) for c in spec.closures], dtype=np.int64)
        cf2 = np.array([frames.index(c.frame2) for c in spec.closures], dtype=np.int64)
        ee = frames.index(spec.end_effector)
        pin.framesForwardKinematics(model, data, q)
        R0 = np.array(data.oMf[fids[ee]].rotation, dtype=float)
        self._g = (parent, np.array(kind, dtype=np.int64), np.array(axes, dtype=float).reshape(n, 3), jR, jt,
                   fparent, fR, ft, anc, ctype, cf1, cf2, int(ee), np.array(self.task_axes, dtype=np.int64), R0,
                   bool(self.oriented), float(self.scale))
        self._m = int(sum(3 if t == 0 else 6 for t in ctype) + (3 if self.oriented else 0) + len(self.task_axes))
        lo, hi = robot.lower, robot.upper
        ranged = np.isfinite(lo) & np.isfinite(hi)
        self._centre = np.where(ranged, 0.5 * (np.where(ranged, lo, 0.0) + np.where(ranged, hi, 0.0)), 0.0)
        # structural pattern: the columns each residual row can depend on
        self._nzc, self._nzn = sparsity(self.row_dependencies())

    @functools.cached_property
    def _packed(self) -> tuple[np.ndarray, np.ndarray]:
        return pack(self._g)

    # -- basic properties ------------------------------------------------------------------------
    @property
    def translational(self) -> bool:
        """The actuators never turn the end effector (its orientation rows hold the reference's),
        as opposed to a rotation held by request (`held`)."""
        return self.oriented and not self.held

    @property
    def task_dim(self) -> int:
        """Dimension d of the task space (platform position coordinates)."""
        return len(self.task_axes)

    @property
    def n(self) -> int:
        """Number of joint values (degrees of freedom of the tree)."""
        return self.robot.nv

    @functools.cached_property
    def actuated(self) -> np.ndarray:
        """Degree-of-freedom indices of the actuated joints (sidecar order)."""
        loops = self.robot.loops
        if loops is None:
            raise UnsupportedRobotError(self.robot.name, "the batched closed-loop solver needs a loop sidecar")
        return np.array([self.robot.joint_names.index(a) for a in loops.actuated])

    @functools.cached_property
    def passive(self) -> np.ndarray:
        """Degree-of-freedom indices of the passive joints."""
        return np.array([i for i in range(self.n) if i not in set(self.actuated.tolist())])

    @functools.cached_property
    def limited(self) -> np.ndarray:
        """Joints whose limits bind: finite and (revolute) narrower than a full turn."""
        lo, hi = self.robot.lower, self.robot.upper
        kind = self._g[1]
        return np.isfinite(lo) & np.isfinite(hi) & ((kind == PRISMATIC) | (hi - lo < 2 * math.pi - 1e-9))

    def _points(self, points: np.ndarray) -> np.ndarray:
        try:  # a single point (ragged input is no point: task_points says what is wrong with it)
            one = np.ndim(points) == 1 and np.shape(points)[0] == self.task_dim
        except ValueError:
            one = False
        return task_points(np.asarray(points)[None] if one else points, self.task_dim)

    # -- kernels ---------------------------------------------------------------------------------
    def newton(self, targets: np.ndarray, x0: np.ndarray, iters: int = 40, tol: float = TOL,
               free: np.ndarray | None = None, rows: np.ndarray | None = None, pinned: bool = False
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Levenberg-Marquardt rows: (R, d) targets, (R, n) starts -> (x, max |residual| [m], iterations).

        free: (n,) bool, the unknowns that may move (default: all); rows: (m,) bool, the equations
        solved (default: all); pinned: place the end effector's body at each target (orientation
        R_0) whatever its ancestors' values (`oriented`, with a 3D task, only): the
        other closures are then solved against the platform where it must be, even where the
        chain that carries it in the tree cannot put it there.

        Raises:
            UnsupportedRobotError: pinned on a mechanism whose orientation is not held, or without a 3D task.
        """
        if pinned and not self.can_pin:
            raise UnsupportedRobotError(self.robot.name, "pinning the end effector needs its orientation held "
                                                         "(a translational mechanism or a held rotation) and a 3D "
                                                         "position task")
        free = np.ones(self.n, dtype=np.bool_) if free is None else np.asarray(free, dtype=np.bool_)
        roww = np.ones(self._m) if rows is None else np.asarray(rows, dtype=float)
        t = np.ascontiguousarray(targets, dtype=float)
        x0 = np.ascontiguousarray(x0, dtype=float)
        x = np.empty_like(x0)
        res = np.empty(len(t))
        its = np.empty(len(t), dtype=np.int64)
        if len(t):
            jit.call(lm_kernel, t, x0, *self._packed, self._m, self._nzc, self._nzn, self._centre, free, roww, iters, tol, x,
                     res, its, bool(pinned))
        return x, res, its

    def evaluate(self, targets: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Residuals (R, m), Jacobians (R, m, n) and positions [m] (R, n + F, 3): every joint origin
        (model order), then the frames of `frames` (closure frames, end effector)."""
        t = np.ascontiguousarray(targets, dtype=float)
        x = np.ascontiguousarray(x, dtype=float)
        R = len(t)
        r = np.empty((R, self._m))
        J = np.empty((R, self._m, self.n))
        pos = np.empty((R, self.n + self._g[5].shape[0], 3))
        if R:
            eval_kernel(t, x, *self._packed, r, J, pos)
        return r, J, pos

    def require_unheld(self, what: str) -> None:
        """Raise UnsupportedRobotError for `what` with a held orientation (`held`): its Jacobians
        relate the actuator rates to the whole twist, which the position task's do not."""
        if self.held:
            raise UnsupportedRobotError(self.robot.name, f"{what} are not done with the end effector held at a "
                                                         "rotation (its six actuators drive the whole pose)")

    def hold_rotation(self, R: np.ndarray) -> None:
        """Hold the end effector at the world rotation R (3, 3) from now on: R_0 in the compiled
        model (the kernels read it from the packed arrays, rebuilt here)."""
        g = list(self._g)
        g[14] = np.array(R, dtype=float)
        self._g = tuple(g)
        self.__dict__.pop("_packed", None)

    @property
    def held_rotation(self) -> np.ndarray:
        """The (3, 3) rotation R_0 the orientation rows hold (the reference's for a translational
        mechanism)."""
        return np.array(self._g[14])

    # -- residual rows ---------------------------------------------------------------------------
    @property
    def can_pin(self) -> bool:
        """`newton(pinned=True)` applies: the orientation held, every position axis the task."""
        return self.oriented and self.task_dim == 3

    @functools.cached_property
    def task_rows(self) -> tuple[int, ...]:
        """Residual rows of the task: the end effector's orientation (if held) and position."""
        k = len(self.task_axes) + (3 if self.oriented else 0)
        return tuple(range(self._m - k, self._m))

    def row_dependencies(self, pinned: bool = False) -> np.ndarray:
        """(m, n) bool: the unknowns each residual row can depend on (its frames' ancestors).

        With pinned (`newton(pinned=True)`) the end effector's body is placed by the target, so
        frames on it or below it no longer depend on its ancestors, and the task rows on nothing."""
        parent, fparent, anc, ctype, cf1, cf2, ee = (self._g[i] for i in (0, 5, 8, 9, 10, 11, 12))
        anc = anc.copy()
        if pinned:
            above = np.zeros(self.n, dtype=bool)  # the end effector's joint and its ancestors
            j = int(fparent[ee])
            while j >= 0:
                above[j] = True
                j = int(parent[j])
            below = anc[:, int(fparent[ee])]  # frames carried by the end effector's joint
            anc[below] &= ~above
        return row_pattern(anc, ctype, cf1, cf2, ee, len(self.task_rows))

    def _row_groups(self) -> list[tuple[int, ...]]:
        groups, k = [], 0
        for t in self._g[9]:
            size = 3 if t == 0 else 6
            groups.append(tuple(range(k, k + size)))
            k += size
        if self.oriented:
            groups.append(tuple(range(k, k + 3)))
            k += 3
        groups.append(tuple(range(k, k + self.task_dim)))
        return groups
