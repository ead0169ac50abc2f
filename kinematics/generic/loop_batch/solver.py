"""`LoopBatch`, the batched closed-loop solver: built from a robot (`from_robot`: the task, the
compiled model, the blocks and the atlas), it solves every branch at many targets (`ik`) and gives
their margins (`margin`) to the volume engine; `loop_batch` caches one per robot.

**Task.** At the sidecar's reference configuration the constrained Jacobian (Pinocchio,
`ClosedLoop.constrained_jacobian`) tells what the actuators move: if they never turn the end
effector the mechanism is translational (task = position, orientation held at R_0: the 3-[P2(US)],
the Delta); otherwise the task is the d = (number of actuators) position axes best determined by
them (the planar five-bar: x, y; for two actuators and a planar motion, `motion_plane`'s plane).
Mechanisms whose actuators drive a rotation of the end effector
(a task that needs orientation coordinates) raise UnsupportedRobotError, unless they have six
actuators and an `orientation` is given: the end effector is then *held* at that rotation (the same
three orientation rows as a translational mechanism's: `oriented` and `held`) and the task is its
position, the constant-orientation workspace of a 6-DOF leg or platform. The reference
configuration is first brought to that orientation at the reference position by continuation
(HOLD_STEPS rotations along the geodesic from the reference orientation, each solved from the
last); a rotation it cannot reach there is refused.

**What the search guarantees.** With the block solver (the default) the restarts a block slot gets
at a target are a function of the target's coordinates, the block and the slot (`compiled.
restart_base`): a target whose slot is restarted gets the same restarts in any batch, at any row,
after any earlier call. A slot whose start closed on a root of the other sign in the same
assembly (the five-bar's other elbow) gets up to RESTART_ROUNDS x `restarts` starts instead of
`restarts`: its roots exist there in general (a block of revolute joints maps a torus of angles,
a map of degree 0: at a regular target as many roots of each sign).
Not guaranteed: the first starts (a neighbour's end from the warm cache or the batch's coarser
levels, whether the atlas start is retried, and the neighbours' verdicts that gate restarts)
depend on the batch's composition and on earlier calls, so a branch found from a neighbour in one
call can be missed by a colder one; and every start can miss a basin.

**What the search can miss.** A branch that exists at a target but is reached from none of the
starts (a block's basin missed by the neighbour's end, the atlas configuration and the restarts)
is reported absent (margin < 0: minus the smallest residual of the starts aimed at it, ~0 where
they all closed on another slot's root): most likely in a branch region that does not contain the
reference position's branch of the same label and is far from the batch's other points, or next
to the workspace's boundary where the nearest solved point lies outside, its least-squares point
leads nowhere and the atlas start lies in another basin (restarts are not spent on a labelling
block with no root at all, nor on a block built on closed blocks where the neighbour that gave the
start found no root of that slot either: outside they would cost most of the time). Solutions whose label is
not in the atlas (assembly modes absent at the reference position) are counted in
`BranchSolutions.unlabelled`, not returned. Two physically different poses with the same label at
one target keep only the one nearest the reference (counted in `conflicts`).
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Callable, Sequence

import numpy as np
import pinocchio as pin

from kinematics.errors import InvalidInputError, UnsupportedRobotError
from kinematics.generic.loop_batch.atlas import BranchSolutions
from kinematics.generic.loop_batch.blocks import BlockSolver
from kinematics.generic.loop_batch.compiled import TOL
from kinematics.generic.loop_batch.singular import LoopSingularities
from kinematics.generic.loop_batch.whole import WholeSolver
from kinematics.model.robot import Robot

HOLD_STEPS = 32
"""Rotations of the continuation that brings the reference configuration to a held orientation."""

SOLVERS = ("blocks", "whole")
"""How `LoopBatch.ik` solves: block by block (each block's roots once per branch choice it depends
on, combined into branches) or every unknown of every branch at once (the reference path)."""


def _rng(seed: int | np.random.Generator | None) -> np.random.Generator:
    return seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)


class LoopBatch(BlockSolver, WholeSolver, LoopSingularities):
    """Every working mode of a closed-loop mechanism (URDF tree + loop sidecar), batched.

    Capabilities (all vectorised over targets, task points of shape (N, d)):

    * `task_dim`, `task_axes`, `translational`, `bounding_box()`: the task space;
    * `ik(points)`: joint values of every branch (`BranchSolutions`), `labels` names the branches;
    * `margin(points)`: (N, B + 1) joint-limit margins per branch and their union (the last
      column), the callable `kinematics.analyses.columns.column_volume` takes; `margin_function(branches)`
      selects branches;
    * `jacobians(points, x)`: forward (task rate per actuator rate) and inverse (actuator rate per
      task rate) Jacobians; `singularities(points, x)`: Gosselin-Angeles measures and types.

    Not thread-safe (it keeps a cache of solved points for warm starts); make one per thread.
    Build with `LoopBatch.from_robot`.

    Its parts are the package's modules, one concept each: `model` (the dataclass fields, the
    compiled model, `newton`, `evaluate`), `structure` (blocks, labels, joint groups), `atlas` (the
    branch search), `warm` (warm starts), `margins`, `blocks` and `whole` (the two solvers of
    `ik`), `singular` (velocities and singularities).
    """

    # -- construction ----------------------------------------------------------------------------
    @classmethod
    def from_robot(cls, robot: Robot, *, task_axes: tuple[int, ...] | None = None, seeds: int = 512,
                   restarts: int = 8, rng: int | np.random.Generator | None = 0, solver: str = "blocks",
                   spheres: bool = True, orientation: np.ndarray | str | None = None) -> LoopBatch:
        """Compile a closed-loop robot and find its branches at the reference position.

        Args:
            task_axes: world position axes of the task (default: chosen at the reference, see the
                module docstring).
            seeds: random starts of the branch search at the reference position.
            restarts: random starts per target that misses some branch (`ik`).
            rng: seed of the random starts (the result is deterministic for a fixed seed).
            solver: one of SOLVERS (`ik`).
            spheres: the block solver solves a spherical triple behind a 6D closure in closed form
                (the module `spheres`); False solves every block's unknowns by Levenberg-Marquardt.
            orientation: (3, 3) world rotation of the end effector frame to hold (a mechanism with
                six actuators that turn it; module docstring), "reference" for its rotation at the
                reference configuration, or None.

        Raises:
            UnsupportedRobotError: no sidecar, a joint with several degrees of freedom, a task that
                needs orientation coordinates (without `orientation`), an `orientation` for a
                mechanism without six actuators or whose end effector does not turn, or one the
                end effector is not brought to at the reference position.
            InvalidInputError: `orientation` is not a rotation matrix.
        """
        from kinematics.generic.closedloop import ClosedLoop

        if solver not in SOLVERS:
            from kinematics.errors import UnknownChoiceError

            raise UnknownChoiceError(solver, SOLVERS)
        if robot.loops is None:
            raise UnsupportedRobotError(robot.name, "no loop-closure sidecar (<name>.loops.yaml) next to its URDF")
        model = robot.model
        for jid in range(1, model.njoints):
            if model.joints[jid].nv != 1:
                raise UnsupportedRobotError(robot.name, f"joint {model.names[jid]!r} has {model.joints[jid].nv} "
                                            "degrees of freedom; the batched loop solver takes 1-DOF joints")
        loop = ClosedLoop(robot)
        # closed to rounding (Newton until it stalls): the translational test below compares the
        # end effector's angular rates with 1e-9 of its linear ones, and a pose closed only to
        # ~1e-12 m leaves ~1e-9 of spurious rotation in the constrained Jacobian (robot_delta)
        q, err, _ = loop.newton(loop.reference, tol=0.0)
        if err > 1e-9:
            raise UnsupportedRobotError(robot.name, f"{loop.assembly.description} does not close "
                                        f"(residual {err:.2e} m)")
        G = loop.constrained_jacobian(q)  # 6 x n_actuated
        n_act = len(loop.actuated_dofs)
        if not np.abs(G).max(initial=0.0) > 1e-12:
            raise UnsupportedRobotError(robot.name, f"no actuator moves its end effector {robot.tool_frame!r} (a frame "
                                                    "on the base or on a part the loops hold still): choose another "
                                                    "frame (--tool-frame)")
        lin, ang = G[:3], G[3:]
        size = max(float(np.linalg.norm(lin)), 1e-300)
        translational = float(np.linalg.norm(ang)) * _length(robot, q) <= 1e-9 * size
        pin.framesForwardKinematics(model, robot.data, q)
        ee = pin.SE3(robot.data.oMf[robot.frame_id(robot.loops.end_effector)])  # the reference pose (a copy)
        if isinstance(orientation, str):
            if orientation != "reference":
                raise InvalidInputError("orientation", f"expected a (3, 3) rotation or 'reference', got {orientation!r}")
            orientation = np.array(ee.rotation)
        held = None if orientation is None else _held(robot, orientation, n_act, translational, G, task_axes)
        if held is not None:
            task_axes, translational = (0, 1, 2), True
        if task_axes is None and n_act == 2:
            from kinematics.generic.motion_plane import motion_plane

            # a planar motion's task is its plane (one decision for every command), where the
            # actuators determine both of its axes there
            plane = motion_plane(robot)
            if plane is not None and np.linalg.svd(lin[list(plane.axes)], compute_uv=False)[-1] > 1e-9 * size:
                task_axes = plane.axes
        if task_axes is None:
            best, axes = -1.0, None
            for comb in itertools.combinations(range(3), n_act):
                s = np.linalg.svd(lin[list(comb)], compute_uv=False)
                if s[-1] > best:
                    best, axes = float(s[-1]), comb
            if axes is None or best <= 1e-9 * size:
                raise UnsupportedRobotError(robot.name, "its actuators drive the end effector's orientation; "
                                            "the batched solver handles position tasks only")
            task_axes = tuple(axes)
        self = cls(robot=robot, task_axes=tuple(int(a) for a in task_axes), oriented=translational,
                   scale=_length(robot, q), restarts=restarts, solver=solver, spheres=spheres, held=held is not None)
        self._compile(q)
        self._reference = robot.values_from_configuration(q)
        self._anchor = np.array(ee.translation)[list(self.task_axes)]
        if held is not None and np.abs(held - self.held_rotation).max() > 1e-12:
            self._reference = self._hold(held, self._reference)
        self.blocks = self._find_blocks()
        if self.solver == "blocks":
            try:
                self.block_models  # noqa: B018 - built here so that a failure picks the other solver
            except UnsupportedRobotError:
                # the equations do not split in dependency order: every unknown at once instead
                self.solver = "whole"
        self._find_atlas(seeds, _rng(rng))
        return self

    def _hold(self, R: np.ndarray, x: np.ndarray) -> np.ndarray:
        """The reference joint values x brought, at the reference position, from the end effector's
        reference orientation (the compiled R_0) to R by continuation (module docstring); R_0 is R
        afterwards.

        Raises:
            UnsupportedRobotError: a step of the continuation does not close (residual > TOL).
        """
        from scipy.spatial.transform import Rotation, Slerp

        path = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([self.held_rotation, R])))
        for k, s in enumerate(np.linspace(0.0, 1.0, HOLD_STEPS + 1)[1:], start=1):
            self.hold_rotation(path(s).as_matrix() if k < HOLD_STEPS else R)
            x_new, res, _ = self.newton(self._anchor[None], x[None], iters=60)
            if not res[0] <= TOL:
                raise UnsupportedRobotError(self.robot.name, (
                    f"its end effector {self.robot.tool_frame!r} was not brought to the orientation asked at "
                    f"its reference position {np.round(self._anchor, 6).tolist()} m (the continuation from the reference "
                    f"orientation stalled at step {k} of {HOLD_STEPS}, residual {res[0]:.2e} m): the loops do not close "
                    "with it there, or only through another assembly"))
            x = x_new[0]
        return x

    @property
    def held_orientation(self) -> np.ndarray | None:
        """The (3, 3) world rotation the end effector is held at (`from_robot(orientation=...)`), or None."""
        return self.held_rotation if self.held else None

    @property
    def reference_point(self) -> np.ndarray:
        """The end effector's task coordinates [m] at the reference configuration (where the atlas
        of branches was found)."""
        return self._anchor.copy()

    # -- inverse kinematics and margins ----------------------------------------------------------
    def ik(self, points: np.ndarray, *, warm: bool = True, every_block: bool = False) -> BranchSolutions:
        """Every atlas branch at every task point (the search: the modules `blocks` and `whole`; what
        it can miss: this module's docstring).

        Args:
            points: (N, d) task coordinates [m].
            warm: use (and update) the cache of earlier batches' solutions as starts.
            every_block: (block solver) solve every block even where an earlier one already rules
                out every branch that uses it, so that `end` holds each block's own end everywhere
                (singularity fields outside the workspace); slower outside.
        """
        p = self._points(points)
        if self.solver == "blocks":
            return self._ik_blocks(p, warm, every_block)
        N = len(p)
        if N > 64:
            # continuation inside the batch: a coarse subset first, the rest from its ends
            first = np.arange(0, N, 8)
            sub = self._solve(p[first], warm)
            rest = np.setdiff1d(np.arange(N), first)
            other = self._solve(p[rest], warm, extra=(p[first], sub.end))
            out = _merge(N, (first, sub), (rest, other))
        else:
            out = self._solve(p, warm)
        if warm:
            self._remember(p, out.end)
        return out

    def margin(self, points: np.ndarray, limits: str = "all") -> np.ndarray:
        """(N, B + 1) margins [m]: every branch (order of `labels`), then their union (max).

        limits: "all" or "actuators" (`limit_margin`)."""
        return self.margin_function(None, limits)(points)

    def margin_function(self, branches: Sequence[int] | None = None, limits: str = "all"
                        ) -> Callable[[np.ndarray], np.ndarray]:
        """points (N, d) -> (N, len(branches) + 1): the chosen branches' margins [m], then their
        union, for `kinematics.analyses.columns.column_volume`."""
        cols = list(range(len(self.labels))) if branches is None else list(branches)
        self.limit_margin(np.zeros((1, self.n)), limits)  # validates `limits`

        def margin(points: np.ndarray) -> np.ndarray:
            p = self._points(points)
            # a point given twice is solved once (the volume engine's root brackets of several
            # targets in one column can meet at one abscissa), in first-occurrence order
            _, first, inv = np.unique(p, axis=0, return_index=True, return_inverse=True)
            order = np.argsort(first)
            rank = np.empty_like(order)
            rank[order] = np.arange(len(order))
            sol = self.ik(p[first[order]])
            m = sol.margin if limits == "all" else np.where(sol.found, self.limit_margin(sol.x, limits), sol.margin)
            m = m[:, cols][rank[np.ravel(inv)]]
            return np.concatenate([m, m.max(axis=1, keepdims=True)], axis=1)

        return margin

    def end_effector_positions(self, x: np.ndarray) -> np.ndarray:
        """(R, 3) world positions [m] of the end effector at joint values x (R, n), model order."""
        _, _, pos = self.evaluate(np.zeros((len(x), self.task_dim)), np.asarray(x, dtype=float))
        return pos[:, self.n + self._g[12]]

    def bounding_box(self, samples: int = 20_000, rng: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """A box [m] around the end effector's reachable task coordinates: the end effector's own
        chain sampled within its joint limits (loops ignored: a superset), padded by 5 %. A
        heuristic: a sampled box can miss the chain's extreme poses by about the padding."""
        x = self.random_configurations(samples, np.random.default_rng(rng))
        _, _, pos = self.evaluate(np.zeros((samples, self.task_dim)), x)
        ee = pos[:, self.n + self._g[12], list(self.task_axes)]
        lo, hi = ee.min(axis=0), ee.max(axis=0)
        pad = 0.05 * (hi - lo) + 1e-3 * self.scale
        return lo - pad, hi + pad


def _merge(N: int, *parts: tuple[np.ndarray, BranchSolutions]) -> BranchSolutions:
    first = parts[0][1]
    x = np.empty((N,) + first.x.shape[1:])
    found = np.empty((N,) + first.found.shape[1:], dtype=bool)
    residual = np.empty(found.shape)
    margin = np.empty(found.shape)
    end = np.empty_like(x)
    for idx, s in parts:
        x[idx], found[idx], residual[idx], margin[idx], end[idx] = s.x, s.found, s.residual, s.margin, s.end
    return BranchSolutions(x, found, residual, margin, sum(s.unlabelled for _, s in parts),
                           sum(s.conflicts for _, s in parts), end)


def _held(robot: Robot, orientation: np.ndarray, n_act: int, translational: bool, G: np.ndarray,
          task_axes: tuple[int, ...] | None) -> np.ndarray:
    """`orientation` checked as the rotation `from_robot` holds (its docstring says when it may).

    Raises:
        InvalidInputError: not a rotation matrix, or task axes other than the whole position.
        UnsupportedRobotError: a translational mechanism, not six actuators, or a singular pose.
    """
    R = np.asarray(orientation, dtype=float)
    if R.shape != (3, 3) or not np.isfinite(R).all() or np.abs(R @ R.T - np.eye(3)).max() > 1e-9 \
            or np.linalg.det(R) <= 0:
        raise InvalidInputError("orientation", "expected a (3, 3) rotation matrix (orthonormal, determinant +1)")
    if task_axes is not None and tuple(task_axes) != (0, 1, 2):
        raise InvalidInputError("task_axes", "with a held orientation the task is the whole position (0, 1, 2)")
    if translational:
        raise UnsupportedRobotError(robot.name, "its actuators do not turn the end effector (a translational "
                                                "mechanism): it keeps one orientation, none can be chosen")
    if n_act != 6:
        raise UnsupportedRobotError(robot.name, (
            f"holding the end effector's orientation leaves its 3 position coordinates to exactly 6 actuators "
            f"(3 + 3), this robot has {n_act}"))
    s = np.linalg.svd(G, compute_uv=False)
    if s[-1] <= 1e-9 * s[0]:
        raise UnsupportedRobotError(robot.name, "its 6 actuators do not move the end effector's whole pose at "
                                                "the reference configuration (a singular pose there)")
    return R


def _length(robot: Robot, q: np.ndarray) -> float:
    """Characteristic length [m]: the largest distance of a joint origin from the world origin at q."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    d = [float(np.linalg.norm(data.oMi[j].translation)) for j in range(1, robot.model.njoints)]
    return max(max(d, default=0.0), 1e-3)


def loop_batch(robot: Robot, orientation: np.ndarray | str | None = None) -> LoopBatch:
    """`LoopBatch.from_robot(robot, orientation=orientation)`, cached per robot and orientation."""
    key = orientation if orientation is None or isinstance(orientation, str) else tuple(
        np.asarray(orientation, dtype=float).ravel().tolist())
    return _cached(robot, key)


@functools.lru_cache(maxsize=16)
def _cached(robot: Robot, orientation: tuple[float, ...] | str | None) -> LoopBatch:
    held = np.array(orientation).reshape(3, 3) if isinstance(orientation, tuple) else orientation
    return LoopBatch.from_robot(robot, orientation=held)
