"""A batched closed-loop solver for any URDF tree + loop sidecar: every working mode of many
task-space targets at once, their joint-limit margins and their singularity measures.

**Equations.** The unknowns are all n joint values x (one per degree of freedom, actuated and
passive). The residual stacks, for a target t,

* every closure of the sidecar: p_f1 - p_f2 (3 rows, `point`), plus l o(R_f1, R_f2) (3 more, `6d`);
* the task: the end effector's position along the task axes minus t (d rows), and, for a
  *translational* mechanism, l o(R_ee, R_0): the platform keeps its reference orientation R_0;

with o(A, B) = vee(A B^T - B A^T) / 2 (zero iff A = B near A = B; its derivative there is
w_A - w_B, the world angular velocities) and l the model's characteristic length (`scale`), so
every row is in metres. The Jacobian rows are the differences of the frames' LOCAL_WORLD_ALIGNED
Jacobians (closure rows) and the end effector's own (task rows).

**Task.** At the sidecar's reference configuration the constrained Jacobian (Pinocchio,
`ClosedLoop.constrained_jacobian`) tells what the actuators move: if they never turn the end
effector the mechanism is translational (task = position, orientation held at R_0: the 3-[P2(US)],
the Delta); otherwise the task is the d = (number of actuators) position axes best determined by
them (the planar five-bar: x, y). Mechanisms whose actuators drive a rotation of the end effector
(a task that needs orientation coordinates) raise UnsupportedRobotError: not done yet.

**Solver.** Levenberg-Marquardt on ||r||^2 in compiled kernels, one row (target, start) per
thread at a time: A = J^T J + lam diag(J^T J), dx = -A^-1 J^T r by Cholesky, accepted when ||r||
drops; lam starts at 1e-8 (Gauss-Newton). A slot's first start (a neighbour's end, else the atlas
configuration) updates lam by Nielsen's rule: x max(1/3, 1 - (2 rho - 1)^3) after an accepted
step, rho the actual over the predicted decrease, and x 10, 20, 40, ... (x 2, 4, ... after a first
accepted step) per rejected trial; the atlas retry and the quasi-random restarts divide lam by 10
after each accepted step and multiply it by 10 per rejection (long Gauss-Newton steps: they close
a target's nearly double roots next to a fold and reach more basins). Revolute values are
wrapped to within pi of the middle of their limits. It stops at max|r| <= TOL (a root: the loops
close and the target is met) or when it stalls (a least-squares point: no root near this start;
after 3 steps, an accepted step, or the step the linear model predicts, that lowers ||r||^2 by
less than STALL of it). The kinematics (all joint placements of the tree, frame placements,
Jacobian columns w x (p_f - o_j) / w) are evaluated in the same kernel, not by per-point Pinocchio
calls; a rejected trial evaluates the residual only, an accepted one adds the Jacobian from the
trial's placements.

**Branches (working modes).** With the end effector fixed the equations split into blocks
(`blocks`): groups of rows (a closure, the task) that determine a set of unknowns on their own,
found once from the Jacobian's sparsity (a greedy block-triangular ordering over single rows
groups, then pairs, then triples). A square block that contains an actuated joint decides that
actuator's working mode: the sign of its determinant cannot change without the block losing rank
(a type I singularity), so the vector of those signs labels a branch and is stable across each
singularity-free region of the workspace. The *atlas* of branches is found once, at the end
effector's reference position, from `seeds` random starts within the joint limits (converged,
deduplicated by the positions of every joint origin, labelled).

`ik` then solves (`solver="blocks"`, the default) **block by block**: each block is a small model
of its own (`block_models`: the ancestors of its frames; for a closure of a translational
mechanism with a 3D task the platform placed at the target), with one *slot* per choice of the
labels its held joints depend on, times its own sign for a labelling block (3-[P2(US)], Delta: 2
slots per block, 12 small solves per target instead of 8 of all 18 unknowns). A branch is the
combination of the slots of its labels; it exists where every block has a root in its slot.
Each slot is sought from (1) a solved neighbour's end of that slot (a cache of earlier batches
and, inside a batch, every 64th then every 8th point solved first: continuation, also through the
least-squares points of targets outside), else (2) the atlas configuration of that slot, which is
also tried where a neighbour's end stalled less than the continuation radius from closure (a
neighbour outside the workspace leaves its end at a fold, from which Newton can stall), then (3)
`restarts` quasi-random starts of the block's unknowns where another slot of the block was found
or the block holds joints of earlier blocks that closed. Blocks are solved in a dependency order,
the smallest first; a slot that no live branch needs is skipped, so a target that one limb cannot
reach costs that limb's solves only. A block that later blocks hold values of is solved to
TOL / 100, so that an over-determined block built on it (a second rod) can still close to TOL.
`solver="whole"` solves every unknown of each branch at once (8 rows per target for the
3-[P2(US)]): the reference path the tests hold the block solver to, and 10-15x slower.

A passive sub-chain can reach one position in several ways that are the same mechanism pose (a
universal joint's (a, b) and (a + pi, pi - b), a spherical joint's two Euler triples); they are
merged (same joint-origin positions) and the one closest to the reference configuration is kept,
so the labels and the reported joint values use one representation throughout.

**What the search can miss.** A branch that exists at a target but is reached from none of the
starts (a block's basin missed by the neighbour's end, the atlas configuration and the restarts)
is reported absent (margin < 0): most likely in a branch region that does not contain the
reference position's branch of the same label and is far from the batch's other points, or next
to the workspace's boundary where the nearest solved point lies outside, its least-squares point
leads nowhere and the atlas start lies in another basin (restarts are not spent on a labelling
block with no root at all: outside they would cost most of the time). Solutions whose label is
not in the atlas (assembly modes absent at the reference position) are counted in
`BranchSolutions.unlabelled`, not returned. Two physically different poses with the same label at
one target keep only the one nearest the reference (counted in `conflicts`).

**Margins.** Per branch, the smallest joint-limit slack in metres (prismatic: the distance to the
limit; revolute: the angle times `scale`), over every joint with a finite range narrower than
2 pi; >= 0 inside. Where the branch has no solution, minus the least-squares residual [m] reached
from its best start (< 0; block by block: the largest over the blocks tried, a block skipped
because an earlier one has no root counting for nothing). The union is the largest branch margin.

**Singularities** (Gosselin & Angeles), from the Jacobian U of all rows (closures, orientation,
task) at a solution, U_a / U_p its actuated / passive columns, and P the task rows:

* type I (an actuator rate undetermined by the platform's): iota_I = sigma_min((I - U_p U_p^+) U_a D^-1)
  with D the norms of U_a's columns: 0 iff some actuator can move with the end effector fixed;
  in [0, 1]; a passive freedom that moves no actuator (a gimbal-locked universal joint) is ignored;
* type II (locked actuators do not hold the platform): iota_II = min over passive rates v with
  P v != 0 of |A v| / |P v|, A the closure and orientation rows: 0 iff the end effector can move
  with the actuators locked; dimensionless (rows in metres), not bounded by 1;
* type III: both. A pose is singular when a measure is <= SINGULAR_TOL.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin

from kinematics.errors import InvalidInputError, UnsupportedRobotError
from kinematics.generic.loop_batch.compiled import (
    PRISMATIC,
    REVOLUTE,
    TOL,
    block_kernel,
    eval_kernel,
    lm_kernel,
    pack,
)
from kinematics.generic.loop_batch.compiled import (
    STALL as STALL,
)
from kinematics.generic.loop_batch.margins import assemble_kernel, slack_kernel
from kinematics.generic.singularity import SINGULAR_TOL as SINGULAR_TOL
from kinematics.generic.singularity import SINGULARITY_TYPES as SINGULARITY_TYPES
from kinematics.model.robot import Robot

WARM_RADIUS_FACTOR = 0.1
"""A solved point warm-starts another when closer than this x `scale` [m]."""

CACHE_POINTS = 100_000
"""Solved points kept for warm starts (the most recent first)."""

RECENT_POINTS = 8192
"""Points added to the warm-start cache before its KD-tree is rebuilt (`_WarmCache`)."""

LIMITS = ("all", "actuators")
"""Which joint limits the margins apply."""

SOLVERS = ("blocks", "whole")
"""How `LoopBatch.ik` solves: block by block (each block's roots once per branch choice it depends
on, combined into branches) or every unknown of every branch at once (the reference path)."""



class Block(NamedTuple):
    """Rows that determine some unknowns once the earlier blocks' unknowns are known.

    Attributes:
        rows: residual rows (structurally zero rows left out).
        cols: the unknowns this block determines (degree-of-freedom indices).
        actuated: the block contains an actuated joint.
    """

    rows: tuple[int, ...]
    cols: tuple[int, ...]
    actuated: bool

    @property
    def square(self) -> bool:
        return len(self.rows) == len(self.cols)


class BranchSolutions(NamedTuple):
    """IK of a batch of targets in every branch of the atlas.

    Attributes:
        x: (N, B, n) joint values per target and branch (NaN where not found), model order.
        found: (N, B) the branch has a solution there (loops closed, target met to TOL).
        residual: (N, B) least-squares residual [m] of the best start (0-ish where found).
        margin: (N, B) joint-limit margin [m] where found, minus the residual elsewhere.
        unlabelled: converged solutions whose label is not in the atlas (not returned).
        conflicts: physically different solutions that shared a label at one target.
        end: (N, B, n) where each branch's best start ended: the solution, or the least-squares
            point where there is none (the next targets' warm starts).
    """

    x: np.ndarray
    found: np.ndarray
    residual: np.ndarray
    margin: np.ndarray
    unlabelled: int
    conflicts: int
    end: np.ndarray


class Singularities(NamedTuple):
    """Singularity measures per target and branch (NaN where the branch is absent).

    Attributes:
        iota_I, iota_II: (N, B) the scale-free measures (see the module docstring).
        types: (N, B) 0 none, 1 type I, 2 type II, 3 type III (-1 absent), SINGULARITY_TYPES.
    """

    iota_I: np.ndarray
    iota_II: np.ndarray
    types: np.ndarray


class BlockModel(NamedTuple):
    """One block of the loop equations as a small model of its own (`LoopBatch.block_models`).

    The sub-tree holds the ancestors of the block's frames; the block's unknowns are free, the
    joints that earlier blocks determine are held (their values per branch), and for a closure of a
    translational mechanism with a 3D task the end effector's joint is placed at the target
    (`pinned`: the platform's other ancestors drop out). Its arrays are those of the whole tree's
    model in kind (`g`, packed for the kernels by `pack`; the row pattern; row weights that keep
    only the block's rows), so the same compiled solver runs on either.

    Attributes:
        block: the block.
        joints: degree-of-freedom index of each sub-tree joint.
        free: (n_sub,) the block's unknowns.
        held: sub-tree indices of the joints that earlier blocks determine.
        owner: for each held joint, (earlier block index, position among its `cols`).
        rows: the block's rows in the sub-model (Block.rows order); cols: its unknowns there
            (Block.cols order); middles: the middle joints of concurrent groups among them.
        label: index among `LoopBatch.label_blocks`, -1 for a block that labels no working mode.
        depends: label-block indices whose branch choice the held values depend on (transitively).
        pinned: the end effector's joint is placed at the target.
    """

    block: Block
    joints: np.ndarray
    free: np.ndarray
    held: np.ndarray
    owner: tuple[tuple[int, int], ...]
    rows: np.ndarray
    cols: np.ndarray
    middles: np.ndarray
    label: int
    depends: tuple[int, ...]
    pinned: bool
    g: tuple[Any, ...]
    m: int
    nzc: np.ndarray
    nzn: np.ndarray
    centre: np.ndarray
    weights: np.ndarray


def _row_pattern(anc: np.ndarray, ctype: np.ndarray, cf1: np.ndarray, cf2: np.ndarray, ee: int,
                 task: int) -> np.ndarray:
    """(m, n) bool: the unknowns each residual row can depend on, from the frames' ancestors."""
    out = []
    for k, t in enumerate(ctype):
        out += [anc[cf1[k]] | anc[cf2[k]]] * (3 if t == 0 else 6)
    out += [anc[ee]] * task
    return np.array(out, dtype=bool).reshape(len(out), anc.shape[1])


def _sparsity(pattern: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The kernel's per-row column lists (padded with -1) and their lengths."""
    cols = [np.flatnonzero(row) for row in pattern]
    width = max([len(c) for c in cols] + [1])
    nzn = np.array([len(c) for c in cols], dtype=np.int64)
    nzc = np.array([np.pad(c, (0, width - len(c)), constant_values=-1) for c in cols], dtype=np.int64)
    return nzc.reshape(len(cols), width), nzn



class _WarmCache:
    """Solved points and where their starts ended, for warm starts, in a ring of CACHE_POINTS +
    RECENT_POINTS rows: a KD-tree over the newest CACHE_POINTS at its last rebuild, and the rows
    written since (at most RECENT_POINTS, searched through a small tree of their own). The rows
    the next writes overwrite are never in the big tree, so it stays valid until it is rebuilt, and
    nothing but the new rows is copied: a small batch (a root refinement step) pays neither for a
    tree over every cached point nor for copying the cache."""

    def __init__(self, shape: tuple[int, ...]) -> None:
        self.shape = shape
        self.points = np.empty((0, 0))
        self.ends = np.empty((0,) + shape)
        self.head = 0  # the next row written
        self.count = 0  # rows holding a point
        self.fresh = 0  # rows written since the tree was built
        self.tree: Any = None
        self.tree_rows = np.empty(0, dtype=np.int64)

    def add(self, p: np.ndarray, end: np.ndarray) -> None:
        if not len(self.points):
            self.points = np.empty((CACHE_POINTS + RECENT_POINTS, p.shape[1]))
            self.ends = np.empty((CACHE_POINTS + RECENT_POINTS,) + self.shape)
        size = len(self.points)
        for c in range(0, len(p), RECENT_POINTS):
            piece = slice(c, c + RECENT_POINTS)
            m = len(p[piece])
            if self.fresh + m > RECENT_POINTS:
                self._rebuild()
            rows = (self.head + np.arange(m)) % size
            self.points[rows], self.ends[rows] = p[piece], end[piece]
            self.head = (self.head + m) % size
            self.fresh += m
            self.count = min(self.count + m, size)

    def _rebuild(self) -> None:
        from scipy.spatial import cKDTree

        self.tree_rows = (self.head - 1 - np.arange(min(self.count, CACHE_POINTS))) % len(self.points)
        self.tree = cKDTree(self.points[self.tree_rows], balanced_tree=False, compact_nodes=False)
        self.fresh = 0

    def nearest(self, q: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
        """(distance (N,), ends (N, *shape)) of the nearest cached point within `radius` of each
        row of q (inf and NaN where none)."""
        from scipy.spatial import cKDTree

        dist = np.full(len(q), np.inf)
        ends = np.full((len(q),) + self.shape, np.nan)
        sources = [(self.tree, self.tree_rows)] if self.tree is not None else []
        if self.fresh:
            rows = (self.head - self.fresh + np.arange(self.fresh)) % len(self.points)
            sources.append((cKDTree(self.points[rows], balanced_tree=False, compact_nodes=False), rows))
        for tree, rows in sources:
            d, j = tree.query(q, distance_upper_bound=radius)
            better = d < dist
            dist[better], ends[better] = d[better], self.ends[rows[j[better]]]
        return dist, ends


class _Slots(NamedTuple):
    """The block solver's per-slot results (`LoopBatch._solve_slots`, `block_kernel`)."""

    found: np.ndarray  # (N, K, S)
    dist: np.ndarray  # (N, K, S) distance to the reference of the kept root
    res: np.ndarray  # (N, K, S) best residual of the starts aimed at the slot (inf: not tried; 0: found)
    end: np.ndarray  # (N, K, S, cmax) each block's unknowns per slot: its kept root where found, else
    # where the slot's best start ended
    counts: np.ndarray  # (N, 2) unlabelled roots, conflicts

    @classmethod
    def empty(cls, N: int, K: int, S: int, cmax: int) -> _Slots:
        return cls(np.zeros((N, K, S), dtype=np.bool_), np.full((N, K, S), np.inf),
                   np.full((N, K, S), np.inf), np.full((N, K, S, cmax), np.nan), np.zeros((N, 2), dtype=np.int64))


# -- the mechanism ---------------------------------------------------------------------------------
def _rng(seed: int | np.random.Generator | None) -> np.random.Generator:
    return seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)


@dataclass(eq=False)
class LoopBatch:
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
    """

    robot: Robot
    task_axes: tuple[int, ...]
    translational: bool
    scale: float
    labels: tuple[tuple[int, ...], ...] = ()
    atlas: np.ndarray = field(default_factory=lambda: np.empty((0, 0)))
    blocks: tuple[Block, ...] = ()
    restarts: int = 8
    solver: str = "blocks"
    frames: tuple[str, ...] = ()
    _g: tuple[Any, ...] = ()
    _m: int = 0
    _nzc: np.ndarray = field(default_factory=lambda: np.empty((0, 0), dtype=np.int64))
    _nzn: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    _centre: np.ndarray = field(default_factory=lambda: np.empty(0))
    _reference: np.ndarray = field(default_factory=lambda: np.empty(0))
    _anchor: np.ndarray = field(default_factory=lambda: np.empty(0))
    _warm: _WarmCache | None = None

    # -- construction ----------------------------------------------------------------------------
    @classmethod
    def from_robot(cls, robot: Robot, *, task_axes: tuple[int, ...] | None = None, seeds: int = 512,
                   restarts: int = 8, rng: int | np.random.Generator | None = 0, solver: str = "blocks"
                   ) -> LoopBatch:
        """Compile a closed-loop robot and find its branches at the reference position.

        Args:
            task_axes: world position axes of the task (default: chosen at the reference, see the
                module docstring).
            seeds: random starts of the branch search at the reference position.
            restarts: random starts per target that misses some branch (`ik`).
            rng: seed of the random starts (the result is deterministic for a fixed seed).
            solver: one of SOLVERS (`ik`).

        Raises:
            UnsupportedRobotError: no sidecar, a joint with several degrees of freedom, or a task
                that needs orientation coordinates.
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
        lin, ang = G[:3], G[3:]
        size = max(float(np.linalg.norm(lin)), 1e-300)
        translational = float(np.linalg.norm(ang)) * _length(robot, q) <= 1e-9 * size
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
        self = cls(robot=robot, task_axes=tuple(int(a) for a in task_axes), translational=translational,
                   scale=_length(robot, q), restarts=restarts, solver=solver)
        self._compile(q)
        self._reference = robot.values_from_configuration(q)
        pin.framesForwardKinematics(model, robot.data, q)
        ee_pos = np.array(robot.data.oMf[robot.frame_id(robot.loops.end_effector)].translation)
        self._anchor = ee_pos[list(self.task_axes)]
        self.blocks = self._find_blocks()
        if self.solver == "blocks":
            try:
                self.block_models  # noqa: B018 - built here so that a failure picks the other solver
            except UnsupportedRobotError:
                # the equations do not split in dependency order: every unknown at once instead
                self.solver = "whole"
        self._find_atlas(seeds, _rng(rng))
        return self

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
                   bool(self.translational), float(self.scale))
        self._m = int(sum(3 if t == 0 else 6 for t in ctype) + (3 if self.translational else 0) + len(self.task_axes))
        lo, hi = robot.lower, robot.upper
        ranged = np.isfinite(lo) & np.isfinite(hi)
        self._centre = np.where(ranged, 0.5 * (np.where(ranged, lo, 0.0) + np.where(ranged, hi, 0.0)), 0.0)
        # structural pattern: the columns each residual row can depend on
        self._nzc, self._nzn = _sparsity(self.row_dependencies())

    @functools.cached_property
    def _packed(self) -> tuple[np.ndarray, np.ndarray]:
        return pack(self._g)

    # -- basic properties ------------------------------------------------------------------------
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

    @property
    def branch_names(self) -> tuple[str, ...]:
        """Readable branch labels: one +/- per labelling block."""
        return tuple("".join("+" if s > 0 else "-" for s in lab) for lab in self.labels)

    def _points(self, points: np.ndarray) -> np.ndarray:
        p = np.asarray(points, dtype=float)
        if p.ndim == 1 and p.shape[0] == self.task_dim:
            p = p[None]
        if p.ndim != 2 or p.shape[1] != self.task_dim:
            raise InvalidInputError("points", f"expected shape (N, {self.task_dim}), got {np.shape(points)}")
        if not np.all(np.isfinite(p)):
            raise InvalidInputError("points", "must be finite")
        return np.ascontiguousarray(p)

    # -- kernels ---------------------------------------------------------------------------------
    def newton(self, targets: np.ndarray, x0: np.ndarray, iters: int = 40, tol: float = TOL,
               free: np.ndarray | None = None, rows: np.ndarray | None = None, pinned: bool = False
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Levenberg-Marquardt rows: (R, d) targets, (R, n) starts -> (x, max |residual| [m], iterations).

        free: (n,) bool, the unknowns that may move (default: all); rows: (m,) bool, the equations
        solved (default: all); pinned: place the end effector's body at each target (orientation
        R_0) whatever its ancestors' values (translational mechanisms with a 3D task only): the
        other closures are then solved against the platform where it must be, even where the
        chain that carries it in the tree cannot put it there.

        Raises:
            UnsupportedRobotError: pinned on a mechanism that is not translational with a 3D task.
        """
        if pinned and not self.can_pin:
            raise UnsupportedRobotError(self.robot.name, "pinning the end effector needs a translational "
                                                         "mechanism with a 3D position task")
        free = np.ones(self.n, dtype=np.bool_) if free is None else np.asarray(free, dtype=np.bool_)
        roww = np.ones(self._m) if rows is None else np.asarray(rows, dtype=float)
        t = np.ascontiguousarray(targets, dtype=float)
        x0 = np.ascontiguousarray(x0, dtype=float)
        x = np.empty_like(x0)
        res = np.empty(len(t))
        its = np.empty(len(t), dtype=np.int64)
        if len(t):
            lm_kernel(t, x0, *self._packed, self._m, self._nzc, self._nzn, self._centre, free, roww, iters, tol, x, res, its,
                       bool(pinned))
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

    # -- structure -------------------------------------------------------------------------------
    @property
    def can_pin(self) -> bool:
        """`newton(pinned=True)` applies: translational, with every position axis as the task."""
        return self.translational and self.task_dim == 3

    @functools.cached_property
    def task_rows(self) -> tuple[int, ...]:
        """Residual rows of the task: the end effector's orientation (if held) and position."""
        k = len(self.task_axes) + (3 if self.translational else 0)
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
        return _row_pattern(anc, ctype, cf1, cf2, ee, len(self.task_rows))

    def _row_groups(self) -> list[tuple[int, ...]]:
        groups, k = [], 0
        for t in self._g[9]:
            size = 3 if t == 0 else 6
            groups.append(tuple(range(k, k + size)))
            k += size
        if self.translational:
            groups.append(tuple(range(k, k + 3)))
            k += 3
        groups.append(tuple(range(k, k + self.task_dim)))
        return groups

    def _find_blocks(self) -> tuple[Block, ...]:
        """Greedy block-triangular ordering of the row groups (closures, orientation, task) from the
        Jacobian's pattern at random configurations (entries below 1e-12 x scale count as zero)."""
        rng = np.random.default_rng(12345)
        lo = np.where(self.limited, self.robot.lower, -math.pi)
        hi = np.where(self.limited, self.robot.upper, math.pi)
        x = rng.uniform(lo, hi, (6, self.n))
        _, J, _ = self.evaluate(np.zeros((6, self.task_dim)), x)
        pattern = np.any(np.abs(J) > 1e-12 * max(self.scale, 1e-300), axis=0)  # (m, n)
        self._pattern = pattern
        live = pattern.any(axis=1)
        groups = [tuple(i for i in g if live[i]) for g in self._row_groups()]
        groups = [g for g in groups if g]
        act = set(self.actuated.tolist())
        known: set[int] = set()
        blocks: list[Block] = []
        remaining = list(range(len(groups)))
        while remaining:
            chosen = None
            for size in (1, 2, 3):
                best = None
                for comb in itertools.combinations(remaining, size):
                    rows = tuple(i for k in comb for i in groups[k])
                    cols = set(np.flatnonzero(pattern[list(rows)].any(axis=0)).tolist()) - known
                    if len(cols) <= len(rows):
                        key = (len(cols) != len(rows), len(rows))  # square first, then small
                        if best is None or key < best[0]:
                            best = (key, comb, rows, cols)
                if best is not None:
                    chosen = best[1:]
                    break
            if chosen is None:
                rows = tuple(i for k in remaining for i in groups[k])
                cols = set(range(self.n)) - known
                chosen = (tuple(remaining), rows, cols)
            comb, rows, cols = chosen
            blocks.append(Block(tuple(rows), tuple(sorted(cols)), bool(cols & act)))
            known |= cols
            remaining = [k for k in remaining if k not in comb]
        return tuple(blocks)

    @property
    def label_blocks(self) -> tuple[Block, ...]:
        """The square blocks with an actuated joint: the sign of each one's determinant labels a
        working mode."""
        return tuple(b for b in self.blocks if b.actuated and b.square and b.cols)

    def label_of(self, J: np.ndarray, x: np.ndarray) -> np.ndarray:
        """(R, L) branch labels at solutions x with Jacobians J: per labelling block, the sign of its
        determinant times sign(cos b) of every concurrent group's middle angle b in the block. A
        group contributes exactly a factor cos b to the determinant (its joints' columns are a
        fixed map of their angular-velocity axes, whose determinant is +-cos b), so the product
        does not depend on the group's representation and keeps its sign through the group's own
        gimbal lock; 0 where the block is singular (type I)."""
        out = np.empty((len(J), len(self.label_blocks)), dtype=np.int8)
        for k, b in enumerate(self.label_blocks):
            sub = J[:, list(b.rows)][:, :, list(b.cols)]
            sign = np.sign(np.linalg.det(sub))
            for grp in self.concurrent_groups:
                if grp[1] in b.cols:
                    sign = sign * np.sign(np.cos(x[:, grp[1]]))
            out[:, k] = sign.astype(np.int8)
        return out

    @functools.cached_property
    def block_models(self) -> tuple[BlockModel, ...]:
        """Each block of `blocks` as a small model of its own (`BlockModel`), for the block solver."""
        parent, kind, axis, jR, jt, fparent, fR, ft, anc, ctype, cf1, cf2, ee, taxes, R0, orient, scale = self._g
        groups = self._row_groups()
        nc = len(ctype)
        carrier = int(fparent[ee])
        task_rows = set(self.task_rows)
        label_index = {b: k for k, b in enumerate(self.label_blocks)}
        owner = np.full(self.n, -1)
        middle = {grp[1] for grp in self.concurrent_groups}
        models: list[BlockModel] = []
        for k, blk in enumerate(self.blocks):
            rows = set(blk.rows)
            closures = [c for c in range(nc) if rows & set(groups[c])]
            task = bool(rows & task_rows)
            pinned = self.can_pin and not task
            frames = sorted({int(cf1[c]) for c in closures} | {int(cf2[c]) for c in closures}
                            | ({int(ee)} if task or pinned else set()))
            joints: set[int] = set()
            for f in frames:
                chain = set(np.flatnonzero(anc[f]).tolist())
                if pinned and anc[f, carrier]:  # carried by the placed joint: the path below it only
                    chain = {j for j in chain if self._descends(j, carrier)}
                joints |= chain
            js = np.array(sorted(joints), dtype=np.int64)
            where = {int(j): i for i, j in enumerate(js)}
            sub_parent = np.array([-1 if (pinned and j == carrier) or parent[j] < 0 else where[int(parent[j])]
                                   for j in js], dtype=np.int64)
            sub_anc = np.zeros((len(frames), len(js)), dtype=np.bool_)
            for i, f in enumerate(frames):
                j = where[int(fparent[f])]
                while j >= 0:
                    sub_anc[i, j] = True
                    j = int(sub_parent[j])
            fi = {f: i for i, f in enumerate(frames)}
            # an end effector the block does not use points at its first frame; its rows weigh 0
            sub_ee = fi.get(int(ee), 0)
            sub_fparent = np.array([where[int(fparent[f])] for f in frames], dtype=np.int64)
            held_orient = bool(orient) and task
            sub_ctype = np.array([ctype[c] for c in closures], dtype=np.int64)
            g = (sub_parent, kind[js], axis[js], jR[js], jt[js], sub_fparent, fR[frames], ft[frames], sub_anc,
                 sub_ctype, np.array([fi[int(cf1[c])] for c in closures], dtype=np.int64),
                 np.array([fi[int(cf2[c])] for c in closures], dtype=np.int64), int(sub_ee), taxes, R0,
                 held_orient, float(scale))
            # full row -> sub-model row
            to_sub: dict[int, int] = {}
            r = 0
            for c in closures:
                for i in groups[c]:
                    to_sub[i] = r
                    r += 1
            if held_orient:
                for i in groups[nc]:
                    to_sub[i] = r
                    r += 1
            for i in groups[-1]:
                to_sub[i] = r
                r += 1
            m = r
            weights = np.zeros(m)
            weights[[to_sub[i] for i in blk.rows]] = 1.0
            pattern = _row_pattern(sub_anc, g[9], g[10], g[11], int(sub_ee), m - sum(3 if t == 0 else 6
                                                                                       for t in sub_ctype))
            pattern[weights == 0.0] = False
            nzc, nzn = _sparsity(pattern)
            free = np.isin(js, blk.cols)
            # an ancestor the block's rows do not depend on (a revolute turning the end effector
            # about its own point, for a position task) is neither solved nor held: the kernel
            # leaves it at 0, which changes nothing the block measures
            held = np.array([i for i, j in enumerate(js) if not free[i] and not (pinned and j == carrier)
                             and (owner[j] >= 0 or self._pattern[list(blk.rows), j].any())], dtype=np.int64)
            own = tuple((int(owner[js[i]]), self.blocks[int(owner[js[i]])].cols.index(int(js[i]))) for i in held)
            if any(o < 0 for o, _ in own):
                raise UnsupportedRobotError(self.robot.name, f"block {k} of the loop equations uses a joint that no "
                                            "earlier block determines")
            depends: set[int] = set()
            for o, _ in own:
                depends |= set(models[o].depends)
                if models[o].label >= 0:
                    depends.add(models[o].label)
            models.append(BlockModel(
                block=blk, joints=js, free=free, held=held, owner=own,
                rows=np.array([to_sub[i] for i in blk.rows], dtype=np.int64),
                cols=np.array([where[c] for c in blk.cols], dtype=np.int64),
                middles=np.array([where[c] for c in blk.cols if c in middle], dtype=np.int64),
                label=label_index.get(blk, -1), depends=tuple(sorted(depends)), pinned=pinned, g=g, m=m,
                nzc=nzc, nzn=nzn, centre=self._centre[js], weights=weights))
            owner[list(blk.cols)] = k
        return tuple(models)

    # -- branch search ---------------------------------------------------------------------------
    def random_configurations(self, count: int, rng: np.random.Generator) -> np.ndarray:
        """(count, n) joint values uniform within the limits (unlimited revolute: a full turn)."""
        lo = np.where(self.limited, self.robot.lower, self._centre - math.pi)
        hi = np.where(self.limited, self.robot.upper, self._centre + math.pi)
        return rng.uniform(lo, hi, (count, self.n))

    def seed_configurations(self, count: int, rng: np.random.Generator) -> np.ndarray:
        """(count, n) random starts of the branch search: uniform over each limited joint's range
        widened by half its span on both sides (roots just outside the limits still attract
        starts), a full turn for the other revolute joints."""
        lo, hi = self.robot.lower, self.robot.upper
        span = np.where(self.limited, hi - lo, 0.0)
        lo = np.where(self.limited, lo - 0.5 * span, self._centre - math.pi)
        hi = np.where(self.limited, hi + 0.5 * span, self._centre + math.pi)
        return rng.uniform(lo, hi, (count, self.n))

    @functools.cached_property
    def concurrent_groups(self) -> tuple[tuple[int, ...], ...]:
        """Pairs and triples of revolute joints, each the only child of the previous one, with a
        common origin and mutually perpendicular axes, no closure or end-effector frame on their
        inner links: universal joints and Euler-angle spherical joints. (a, b[, c]) and
        (a + pi, pi - b[, c + pi]) place every link after the group identically."""
        parent, kind, axis, jR, jt, fparent = (self._g[i] for i in range(6))
        children: dict[int, list[int]] = {}
        for j, p in enumerate(parent):
            children.setdefault(int(p), []).append(j)
        framed = set(int(f) for f in fparent)

        def follows(j1: int, j2: int) -> bool:
            """j2 is j1's only child, revolute, at j1's origin, its axis perpendicular to j1's."""
            if children.get(j1, []) != [j2] or kind[j2] != REVOLUTE or j1 in framed:
                return False
            a2 = jR[j2] @ axis[j2]  # in j1's frame
            return float(np.linalg.norm(jt[j2])) <= 1e-12 and abs(float(axis[j1] @ a2)) <= 1e-9

        groups: list[tuple[int, ...]] = []
        used: set[int] = set()
        for j1 in range(len(parent)):
            if kind[j1] != REVOLUTE or j1 in used or j1 in self.actuated:
                continue
            (j2,) = children.get(j1, [-1]) if len(children.get(j1, [])) == 1 else (-1,)
            if j2 < 0 or j2 in self.actuated or not follows(j1, j2):
                continue
            group = [j1, j2]
            kids = children.get(j2, [])
            if len(kids) == 1 and kids[0] not in self.actuated and j2 not in framed:
                j3 = kids[0]
                # axes in j2's frame: j1's axis is R2^T a1 (j2's own rotation does not turn its axis)
                a1 = jR[j2].T @ axis[j1]
                if kind[j3] == REVOLUTE and float(np.linalg.norm(jt[j3])) <= 1e-12:
                    a3 = jR[j3] @ axis[j3]
                    if abs(float(a3 @ a1)) <= 1e-9 and abs(float(a3 @ axis[j2])) <= 1e-9:
                        group.append(j3)
            groups.append(tuple(group))
            used.update(group)
        return tuple(groups)

    @functools.cached_property
    def flippable_groups(self) -> tuple[tuple[int, ...], ...]:
        """The concurrent groups whose other representation is the same pose of every link after
        them: triples (Euler), and pairs (a, b) -> (a + pi, pi - b), which spin the child link by
        pi about u1 x u2, when the child carries no joint and only point-closure frames on that
        axis (a rod between a universal and a spherical joint)."""
        parent, _, axis, jR, _, fparent, _, ft = (self._g[i] for i in range(8))
        point_frames = set(int(f) for f, t in zip(self._g[10], self._g[9], strict=True) if t == 0)
        point_frames |= set(int(f) for f, t in zip(self._g[11], self._g[9], strict=True) if t == 0)
        out: list[tuple[int, ...]] = []
        for grp in self.concurrent_groups:
            if len(grp) == 3:
                out.append(grp)
                continue
            j1, j2 = grp
            if np.any(parent == j2):
                continue
            u3 = np.cross(jR[j2].T @ axis[j1], axis[j2])  # in j2's frame
            frames = np.flatnonzero(fparent == j2)
            if all(int(f) in point_frames and float(np.linalg.norm(np.cross(ft[f], u3))) <= 1e-12 for f in frames):
                out.append(grp)
        return tuple(out)

    def canonical(self, x: np.ndarray) -> np.ndarray:
        """One representation per pose where the model allows it exactly: every flippable group's
        middle angle b within [-pi/2, pi/2] ((a, b[, c]) -> (a + pi, pi - b[, c + pi]) where
        cos b < 0), angles wrapped as the solver."""
        x = np.array(x, dtype=float)
        for grp in self.flippable_groups:
            flip = np.cos(x[..., grp[1]]) < 0
            x[..., grp[0]] = np.where(flip, x[..., grp[0]] + math.pi, x[..., grp[0]])
            x[..., grp[1]] = np.where(flip, math.pi - x[..., grp[1]], x[..., grp[1]])
            if len(grp) == 3:
                x[..., grp[2]] = np.where(flip, x[..., grp[2]] + math.pi, x[..., grp[2]])
        revolute = self._g[1] == REVOLUTE
        c = self._centre[revolute]
        x[..., revolute] = (x[..., revolute] - c + math.pi) % (2 * math.pi) + c - math.pi
        return x

    def _distance_to_reference(self, x: np.ndarray) -> np.ndarray:
        d = x - self._reference
        revolute = self._g[1] == REVOLUTE
        d[..., revolute] = (d[..., revolute] + math.pi) % (2 * math.pi) - math.pi
        return np.sum(d * d, axis=-1)

    def _find_atlas(self, seeds: int, rng: np.random.Generator) -> None:
        x0 = np.vstack([self._reference, self.seed_configurations(seeds, rng)])
        t = np.repeat(self._anchor[None], len(x0), axis=0)
        x, res, _ = self.newton(t, x0, iters=100)
        ok = res <= TOL
        if not ok.any():
            raise UnsupportedRobotError(self.robot.name, "no start closed the loops at the reference position")
        x, t = self.canonical(x[ok]), t[ok]
        _, J, _ = self.evaluate(t, x)
        lab = self.label_of(J, x)
        keep = np.all(lab != 0, axis=1)
        x, lab = x[keep], lab[keep]
        dist = self._distance_to_reference(x)
        best: dict[tuple[int, ...], int] = {}
        for i in np.argsort(dist):
            key = tuple(int(v) for v in lab[i])
            best.setdefault(key, int(i))
        keys = sorted(best, reverse=True)
        self.labels = tuple(keys)
        self.atlas = np.array([x[best[k]] for k in keys])

    def ik(self, points: np.ndarray, *, warm: bool = True, every_block: bool = False) -> BranchSolutions:
        """Every atlas branch at every task point (see the module docstring for the search).

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

    def _remember(self, p: np.ndarray, end: np.ndarray) -> None:
        """Keep solved points and their ends for the next batches' warm starts (`_WarmCache`)."""
        if self._warm is None or self._warm.shape != end.shape[1:]:
            self._warm = _WarmCache(end.shape[1:])
        self._warm.add(p, end)

    def _nearest_cached(self, p: np.ndarray, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
        """`_WarmCache.nearest` within the continuation radius (none if nothing of `shape` is cached)."""
        if self._warm is None or self._warm.shape != shape:
            return np.full(len(p), np.inf), np.full((len(p),) + shape, np.nan)
        return self._warm.nearest(p, WARM_RADIUS_FACTOR * self.scale)

    def forget(self) -> None:
        """Drop the warm-start cache."""
        self._warm = None

    def _solve(self, p: np.ndarray, warm: bool,
               extra: tuple[np.ndarray, np.ndarray] | None = None) -> BranchSolutions:
        from scipy.spatial import cKDTree

        N, B, n = len(p), len(self.labels), self.n
        best_x = np.full((N, B, n), np.nan)
        best_d = np.full((N, B), np.inf)
        residual = np.full((N, B), np.inf)
        end_x = np.full((N, B, n), np.nan)  # where each slot's best start ended (root or least-squares point)
        counters = [0, 0]
        codes = (np.array(self.labels, dtype=np.int64) + 1) @ (3 ** np.arange(len(self.labels[0]), dtype=np.int64))
        code_slot = np.argsort(codes)
        codes_sorted = codes[code_slot]

        def attempt(idx: np.ndarray, slot: np.ndarray, x0: np.ndarray, iters: int) -> None:
            if not len(idx):
                return
            x, res, _ = self.newton(p[idx], x0, iters=iters)
            better = res < residual[idx, slot]
            order = np.argsort(-res[better])  # ties: the smallest residual is written last
            end_x[idx[better][order], slot[better][order]] = x[better][order]
            np.minimum.at(residual, (idx, slot), res)
            ok = res <= TOL
            if not ok.any():
                return
            i, x, slot = idx[ok], self.canonical(x[ok]), slot[ok]
            _, J, _ = self.evaluate(p[i], x)
            lab = self.label_of(J, x)
            # label -> slot through the labels' codes in base 3 (-1, 0, +1 -> 0, 1, 2)
            key = (lab.astype(np.int64) + 1) @ (3 ** np.arange(lab.shape[1], dtype=np.int64))
            target = np.full(len(key), -1)
            pos = np.searchsorted(codes_sorted, key)
            hit = (pos < len(codes_sorted)) & (codes_sorted[np.minimum(pos, len(codes_sorted) - 1)] == key)
            target[hit] = code_slot[pos[hit]]
            counters[0] += int(np.sum(target < 0))
            good = target >= 0
            i, x, target = i[good], x[good], target[good]
            d = self._distance_to_reference(x)
            # per (target, slot): the candidate nearest the reference beats the one in place
            order = np.lexsort((d, target, i))
            i, x, target, d = i[order], x[order], target[order], d[order]
            first = np.ones(len(i), dtype=bool)
            first[1:] = (i[1:] != i[:-1]) | (target[1:] != target[:-1])
            dup = ~first & ~np.all(np.abs(x[:, self.actuated] - np.repeat(x[first][:, self.actuated],
                                   np.diff(np.r_[np.flatnonzero(first), len(i)]), axis=0)) <= 1e-9, axis=1)
            counters[1] += int(np.sum(dup))
            i, x, target, d = i[first], x[first], target[first], d[first]
            better = d < best_d[i, target]
            i, x, target, d = i[better], x[better], target[better], d[better]
            best_d[i, target], best_x[i, target], end_x[i, target] = d, x, x
            residual[i, target] = 0.0

        # (1) neighbours (earlier batches, this batch's coarse subset): each slot from the same
        # slot's root or least-squares point there (continuation)
        tried = np.zeros((N, B), dtype=bool)
        sources = [self._nearest_cached(p, (B, n))] if warm else []
        if extra is not None and len(extra[0]):
            dist, j = cKDTree(extra[0]).query(p, distance_upper_bound=WARM_RADIUS_FACTOR * self.scale)
            sources.append((dist, np.where(np.isfinite(dist)[:, None, None], extra[1][np.minimum(j, len(extra[0]) - 1)],
                                           np.nan)))
        for dist, ends in sources:
            near = np.isfinite(dist)
            has = np.isfinite(ends[:, :, 0])
            idx, slot = np.nonzero(near[:, None] & has & ~np.isfinite(best_d))
            attempt(idx, slot, ends[idx, slot], 20)
            tried[idx, slot] = True
        # (2) the atlas configuration of each label not started from a neighbour
        idx, slot = np.nonzero(~tried & ~np.isfinite(best_d))
        attempt(idx, slot, self.atlas[slot], 40)
        # (3) block by block, where some but not all branches were found
        some = np.isfinite(best_d).any(axis=1) & ~np.isfinite(best_d).all(axis=1)
        idx, slot = np.nonzero(some[:, None] & ~np.isfinite(best_d))
        if self.restarts and len(idx):
            attempt(idx, slot, self.blockwise(p[idx], slot, np.random.default_rng(len(p))), 20)
        found = np.isfinite(best_d)
        residual = np.where(found, 0.0, np.where(np.isfinite(residual), residual, np.nan))
        margin = np.where(found, self.limit_margin(np.nan_to_num(best_x)),
                          -np.maximum(np.nan_to_num(residual, nan=1.0), 1e-300))
        return BranchSolutions(best_x, found, residual, margin, counters[0], counters[1], end_x)

    @functools.cached_property
    def _block_tables(self) -> dict[str, Any]:
        """The block solver's packed arrays (`block_kernel`): per block its slots (one per choice
        of the labels it depends on, times its own sign for a labelling block), the slot each
        branch uses, the starts, and the sub-model indices padded to the largest block."""
        models = self.block_models
        K, B = len(models), len(self.labels)
        labels = np.array(self.labels, dtype=np.int64).reshape(B, -1)
        cmax = max(len(bm.cols) for bm in models)
        keys: list[list[tuple[int, ...]]] = []
        bslot = np.zeros((B, K), dtype=np.int64)
        for k, bm in enumerate(models):
            own = (bm.label,) if bm.label >= 0 else ()
            key = [tuple(int(v) for v in labels[b, list(bm.depends) + list(own)]) for b in range(B)]
            uniq = sorted(set(key), reverse=True)
            keys.append(uniq)
            bslot[:, k] = [uniq.index(c) for c in key]
        S = max(len(u) for u in keys)
        nslot = np.array([len(u) for u in keys], dtype=np.int64)
        rep = np.zeros((K, S), dtype=np.int64)  # a branch that uses each slot
        for k in range(K):
            for s in range(nslot[k]):
                rep[k, s] = int(np.flatnonzero(bslot[:, k] == s)[0])
        land = np.full((K, S, 3), -1, dtype=np.int64)
        for k, bm in enumerate(models):
            for s, slot_key in enumerate(keys[k]):
                if bm.label < 0:
                    land[k, s] = s
                    continue
                for sign in (-1, 0, 1):
                    other = slot_key[:-1] + (sign,)
                    land[k, s, sign + 1] = keys[k].index(other) if other in keys[k] else -1
        hmax = max([len(bm.held) for bm in models] + [1])
        held = np.zeros((K, hmax), dtype=np.int64)
        held_owner = np.zeros((K, hmax), dtype=np.int64)
        held_pos = np.zeros((K, hmax), dtype=np.int64)
        held_slot = np.zeros((K, S, hmax), dtype=np.int64)
        for k, bm in enumerate(models):
            for h, (o, pos) in enumerate(bm.owner):
                held[k, h], held_owner[k, h], held_pos[k, h] = bm.held[h], o, pos
                held_slot[k, : nslot[k], h] = bslot[rep[k, : nslot[k]], o]
        flippable = self.flippable_groups
        fmax = max([len(bm.cols) for bm in models] + [1])
        flips = np.full((K, fmax, 3), -1, dtype=np.int64)
        nflip = np.zeros(K, dtype=np.int64)
        mmax = max([len(bm.middles) for bm in models] + [1])
        middles = np.zeros((K, mmax), dtype=np.int64)
        cols = np.zeros((K, cmax), dtype=np.int64)
        rows_det = np.zeros((K, cmax), dtype=np.int64)
        ref = np.zeros((K, cmax))
        act = np.zeros((K, cmax), dtype=np.bool_)
        atlas = np.zeros((K, S, cmax))
        lo = np.zeros((K, cmax))
        hi = np.zeros((K, cmax))
        alpha = np.zeros((K, cmax))
        span = np.where(self.limited, self.robot.upper - self.robot.lower, 0.0)
        r_lo = np.where(self.limited, self.robot.lower - 0.5 * span, self._centre - math.pi)
        r_hi = np.where(self.limited, self.robot.upper + 0.5 * span, self._centre + math.pi)
        for k, bm in enumerate(models):
            full = np.array(bm.block.cols, dtype=np.int64)
            nc = len(full)
            where = {int(j): i for i, j in enumerate(bm.joints)}
            q = 0
            for grp in flippable:
                if all(j in bm.block.cols for j in grp):
                    flips[k, q, : len(grp)] = [where[j] for j in grp]
                    q += 1
            nflip[k] = q
            middles[k, : len(bm.middles)] = bm.middles
            cols[k, :nc] = bm.cols
            if bm.label >= 0:
                rows_det[k, :nc] = bm.rows
            ref[k, :nc] = self._reference[full]
            act[k, :nc] = np.isin(full, self.actuated)
            atlas[k, : nslot[k], :nc] = self.atlas[rep[k, : nslot[k]]][:, full]
            lo[k, :nc], hi[k, :nc] = r_lo[full], r_hi[full]
            # the additive recurrence of the R_d sequence (plastic-number family): well spread in d dims
            phi = 2.0
            for _ in range(64):
                phi = (1.0 + phi) ** (1.0 / (nc + 1))
            alpha[k, :nc] = (1.0 / phi) ** np.arange(1, nc + 1) % 1.0
        T = (np.array([bm.pinned for bm in models], dtype=np.bool_), np.array([len(bm.cols) for bm in models],
             dtype=np.int64), cols, rows_det, np.array([bm.label for bm in models], dtype=np.int64), middles,
             np.array([len(bm.middles) for bm in models], dtype=np.int64), flips, nflip, held,
             np.array([len(bm.held) for bm in models], dtype=np.int64), held_owner, held_pos, held_slot, land, ref, act,
             np.array([any(o == k for m_ in models for o, _ in m_.owner) for k in range(K)], dtype=np.bool_))
        kernel_models = tuple((*pack(bm.g), bm.m, bm.nzc, bm.nzn, bm.centre, bm.free, bm.weights) for bm in models)
        # solve order: every block after the blocks it holds joints of, the smallest sub-model first
        # among those ready (a target that one limb cannot reach is dropped before the costlier ones)
        order: list[int] = []
        while len(order) < K:
            ready = [k for k in range(K) if k not in order and all(o in order for o, _ in models[k].owner)]
            order.append(min(ready, key=lambda k: (len(models[k].joints), k)))
        full_cols = np.zeros((K, cmax), dtype=np.int64)
        for k, bm in enumerate(models):
            full_cols[k, : len(bm.block.cols)] = bm.block.cols
        return {"models": kernel_models, "T": T, "full_cols": full_cols, "order": order, "nslot": nslot, "bslot": bslot, "atlas": atlas,
                "lo": lo, "hi": hi, "alpha": alpha, "S": S, "cmax": cmax}

    def _ik_blocks(self, p: np.ndarray, warm: bool, every_block: bool = False) -> BranchSolutions:
        """`ik` block by block (`block_models`, `block_kernel`): each block's roots once per choice
        of the branches it depends on, combined into the atlas branches (`assemble_kernel`).
        Warm starts are per block slot: the slot's end at the nearest cached point, or at the
        nearest point of this batch solved before it (coarse levels first), whichever is nearer."""
        from scipy.spatial import cKDTree

        tb = self._block_tables
        N, B, n = len(p), len(self.labels), self.n
        K, S, cmax = len(self.block_models), tb["S"], tb["cmax"]
        radius = WARM_RADIUS_FACTOR * self.scale
        best = np.full(N, np.inf)  # distance to the nearest start's source (inf: none)
        cached = None
        if warm:
            best, cached = self._nearest_cached(p, (K, S, cmax))
        # continuation inside the batch: every 64th point, then every 8th, then the rest, each
        # level from the nearest point of the levels before; the points are taken level by level
        # (order) so that each level's slots are one contiguous slice of the arrays
        # (a batch whose points mostly have a cached neighbour, such as a root refinement step, in one go)
        strides = (1,) if np.isfinite(best).mean() >= 0.9 else (64, 8, 1)
        levels, taken = [], np.zeros(N, dtype=bool)
        for stride in strides:
            level = np.flatnonzero(~taken & (np.arange(N) % stride == 0))
            if len(level) and not (stride > 1 and 8 * stride >= N):
                levels.append(level)
                taken[level] = True
        order = np.concatenate(levels) if levels else np.arange(0)
        q, best = p[order], best[order]
        starts = np.full((N, K, S, cmax), np.nan)
        if cached is not None:
            near = np.isfinite(best)
            starts[near] = cached[order[near]]
        slots = _Slots.empty(N, K, S, cmax)
        a = 0
        for level in levels:
            b = a + len(level)
            if a:
                # the nearest solved point: all its slot ends within the continuation radius (roots
                # and least-squares points alike); farther, its roots only, and only where it is
                # nearer than the reference position (whose roots are the atlas starts)
                d, src = cKDTree(q[:a]).query(q[a:b])
                near = (d <= radius) & (d < best[a:b])
                starts[a:b][near], best[a:b][near] = slots.end[src[near]], d[near]
                far = ~near & ~np.isfinite(best[a:b]) & (d < np.linalg.norm(q[a:b] - self._anchor, axis=1))
                starts[a:b][far] = np.where(slots.found[src[far]][..., None], slots.end[src[far]], np.nan)
            self._solve_slots(q[a:b], starts[a:b], _Slots(*(v[a:b] for v in slots)), every_block)
            a = b
        x = np.empty((N, B, n))
        end_x = np.empty((N, B, n))
        ok = np.empty((N, B), dtype=np.bool_)
        residual = np.empty((N, B))
        margin = np.empty((N, B))
        if N:
            lo, hi, use, unit, pairs, paired, centre = self._slack_args("all")
            assemble_kernel(order, slots.end, slots.found, slots.res, tb["bslot"], tb["full_cols"],
                             tb["T"][1], lo, hi, use, unit, pairs, paired, centre, x, end_x, ok, residual, margin)
        if warm:
            self._remember(q, slots.end)
        return BranchSolutions(x, ok, residual, margin, int(slots.counts[:, 0].sum()), int(slots.counts[:, 1].sum()),
                               end_x)

    def _solve_slots(self, p: np.ndarray, starts: np.ndarray, out: _Slots, every_block: bool = False) -> None:
        """Every block slot at targets p from warm starts (N, K, S, cmax) (NaN: none), written to
        `out` (rows of the caller's arrays); a slot no live branch needs is skipped unless
        every_block."""
        tb = self._block_tables
        N, B = len(p), len(self.labels)
        alive = np.ones((N, B), dtype=np.bool_)
        starts = np.ascontiguousarray(starts)
        for k in tb["order"] if N else ():
            if every_block:
                alive[:] = True
            gi, gf, m, nzc, nzn, centre, free, weights = tb["models"][k]
            block_kernel(k, p, gi, gf, m, nzc, nzn, centre, free, weights, tb["T"], tb["nslot"], tb["bslot"], tb["atlas"], starts, tb["lo"],
                          tb["hi"], tb["alpha"], int(self.restarts), WARM_RADIUS_FACTOR * self.scale, alive, out.found, out.dist, out.res,
                          out.end, out.counts)

    def blockwise(self, targets: np.ndarray, slot: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Starts for branch `slot` at each target, built block by block in the triangular order:
        each block's unknowns are solved from its own equations (the earlier blocks' unknowns
        held), from the atlas values of that branch and, for a labelling block that lands on the
        wrong sign, from `restarts` random values of its unknowns; the best candidate is kept."""
        x = np.array(self.atlas[slot], dtype=float)
        want = np.array(self.labels, dtype=np.int8)[slot]  # (R, L)
        lab_index = {b: k for k, b in enumerate(self.label_blocks)}
        R = len(x)
        for blk in self.blocks:
            if not blk.cols:
                continue
            rows = np.zeros(self._m, dtype=bool)
            rows[list(blk.rows)] = True
            free = np.zeros(self.n, dtype=bool)
            free[list(blk.cols)] = True
            k = lab_index.get(blk)
            tries = 1 + (self.restarts if k is not None else 0)
            starts = np.repeat(x[None], tries, axis=0)  # (tries, R, n)
            if tries > 1:
                rnd = self.seed_configurations(R * (tries - 1), rng).reshape(tries - 1, R, self.n)
                starts[1:, :, list(blk.cols)] = rnd[:, :, list(blk.cols)]
            flat = starts.reshape(-1, self.n)
            tt = np.tile(targets, (tries, 1))
            y, res, _ = self.newton(tt, flat, iters=30, free=free, rows=rows)
            y = self.canonical(y)
            score = res.copy()
            if k is not None:
                _, J, _ = self.evaluate(tt, y)
                sign = self.label_of(J, y)[:, list(self.label_blocks).index(blk)]
                score = np.where(sign == np.tile(want[:, k], tries), score, score + 10.0)
            score = score.reshape(tries, R)
            best = np.argmin(score, axis=0)
            x = y.reshape(tries, R, self.n)[best, np.arange(R)]
        return x

    # -- margins ---------------------------------------------------------------------------------
    def limit_margin(self, x: np.ndarray, limits: str = "all") -> np.ndarray:
        """Smallest joint-limit slack [m] of joint values x (..., n): prismatic distance to the
        limit, revolute angle x `scale`; joints without binding limits are ignored.

        limits: "all" (every joint) or "actuators" (the actuated joints only)."""
        if limits not in LIMITS:
            from kinematics.errors import UnknownChoiceError

            raise UnknownChoiceError(limits, LIMITS)
        x = np.asarray(x, dtype=float)
        if x.shape[-1] != self.n:
            raise InvalidInputError("x", f"expected (..., {self.n}) joint values, got {x.shape}")
        flat = np.ascontiguousarray(x.reshape(-1, self.n))
        out = np.empty(len(flat))
        if len(flat):
            lo, hi, use, unit, pairs, paired, centre = self._slack_args(limits)
            slack_kernel(flat, lo, hi, use, unit, pairs, paired, centre, out)
        return out.reshape(x.shape[:-1])

    def _slack_args(self, limits: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                                np.ndarray]:
        use = self.limited.copy()
        if limits == "actuators":
            use[self.passive] = False
        unit = np.where(self._g[1] == PRISMATIC, 1.0, self.scale)
        pairs = np.array(self.free_pairs, dtype=np.int64).reshape(-1, 2)
        paired = np.zeros(self.n, dtype=np.bool_)
        paired[pairs.ravel()] = True
        return (np.asarray(self.robot.lower, dtype=float), np.asarray(self.robot.upper, dtype=float), use, unit, pairs,
                paired, self._centre)

    @functools.cached_property
    def free_pairs(self) -> tuple[tuple[int, int], ...]:
        """Concurrent pairs that are not flippable but whose other representation changes only
        joints without binding limits below them (a universal joint carrying a platform through an
        Euler spherical joint): the margin takes the better of the two representations."""
        flippable = set(self.flippable_groups)
        out = []
        for grp in self.concurrent_groups:
            if len(grp) != 2 or grp in flippable:
                continue
            below = [j for j in range(self.n) if self._descends(j, grp[1]) and j != grp[1]]
            if not any(self.limited[j] for j in below):
                out.append((grp[0], grp[1]))
        return tuple(out)

    def _descends(self, j: int, ancestor: int) -> bool:
        parent = self._g[0]
        while j >= 0:
            if j == ancestor:
                return True
            j = int(parent[j])
        return False

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
            sol = self.ik(points)
            m = sol.margin if limits == "all" else np.where(sol.found, self.limit_margin(sol.x, limits), sol.margin)
            m = m[:, cols]
            return np.concatenate([m, m.max(axis=1, keepdims=True)], axis=1)

        return margin

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

    # -- velocities and singularities -----------------------------------------------------------
    def _split(self, points: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        p = self._points(points)
        x = np.asarray(x, dtype=float)
        if x.shape[:1] != (len(p),) or x.shape[-1] != self.n:
            raise InvalidInputError("x", f"expected ({len(p)}, [B,] {self.n}) joint values, got {x.shape}")
        xb = x.reshape(len(p), -1, self.n)
        B = xb.shape[1]
        ok = np.all(np.isfinite(xb), axis=-1)
        t = np.repeat(p, B, axis=0)
        _, J, _ = self.evaluate(t, np.nan_to_num(xb.reshape(-1, self.n)))
        return J.reshape(len(p), B, self._m, self.n), ok, xb

    def jacobians(self, points: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(forward, inverse) Jacobians at solutions x (N, [B,] n) of targets (N, d).

        forward: (N, B, d, a): task velocity per actuator rate (locked-actuator passive rates
        eliminated by least squares; meaningless at type II). inverse: (N, B, a, d): actuator
        rates per task velocity (meaningless at type I). NaN where x is NaN.
        """
        J, ok, _ = self._split(points, x)
        a, pa = self.actuated, self.passive
        c = self._m - self.task_dim
        U_inv = np.linalg.pinv(J, rcond=1e-13)  # (N, B, n, m)
        inverse = U_inv[..., a, c:]
        A = J[..., :c, :]
        Pm = J[..., c:, :]
        vp = -np.linalg.pinv(A[..., pa], rcond=1e-13) @ A[..., a]  # (N, B, np, a)
        forward = Pm[..., a] + Pm[..., pa] @ vp
        nan = ~ok[..., None, None]
        return np.where(nan, np.nan, forward), np.where(nan, np.nan, inverse)

    def singularities(self, points: np.ndarray, x: np.ndarray, tol: float = SINGULAR_TOL) -> Singularities:
        """Gosselin-Angeles measures and types at solutions x (N, [B,] n) (module docstring)."""
        J, ok, _ = self._split(points, x)
        a, pa = self.actuated, self.passive
        c = self._m - self.task_dim
        Ua, Up = J[..., a], J[..., pa]
        Ua = Ua / np.maximum(np.linalg.norm(Ua, axis=-2, keepdims=True), 1e-300)
        proj = Ua - Up @ (np.linalg.pinv(Up, rcond=1e-10) @ Ua)
        iota_I = np.linalg.svd(proj, compute_uv=False)[..., -1]
        A, P = J[..., :c, :][..., pa], J[..., c:, :][..., pa]
        _, s, Vt = np.linalg.svd(P, full_matrices=True)
        r = int(np.max(np.sum(s > 1e-10 * np.maximum(s[..., :1], 1e-300), axis=-1)))
        V = np.swapaxes(Vt, -1, -2)
        Y, Z = V[..., :r], V[..., r:]
        AY, AZ = A @ Y, A @ Z
        QAY = AY - AZ @ (np.linalg.pinv(AZ, rcond=1e-10) @ AY)
        iota_II = np.linalg.svd(QAY / s[..., None, :r], compute_uv=False)[..., -1]
        iota_I = np.where(ok, iota_I, np.nan)
        iota_II = np.where(ok, iota_II, np.nan)
        types = np.where(ok, (iota_I <= tol).astype(np.int8) + 2 * (iota_II <= tol).astype(np.int8), -1)
        return Singularities(iota_I, iota_II, types.astype(np.int8))


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


def _length(robot: Robot, q: np.ndarray) -> float:
    """Characteristic length [m]: the largest distance of a joint origin from the world origin at q."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    d = [float(np.linalg.norm(data.oMi[j].translation)) for j in range(1, robot.model.njoints)]
    return max(max(d, default=0.0), 1e-3)


def kernels() -> tuple[Any, ...]:
    """The compiled kernels of this module (for `kinematics.jit`)."""
    return (lm_kernel, eval_kernel, block_kernel, assemble_kernel, slack_kernel)


@functools.lru_cache(maxsize=16)
def loop_batch(robot: Robot) -> LoopBatch:
    """`LoopBatch.from_robot(robot)`, cached per robot."""
    return LoopBatch.from_robot(robot)
