"""Reachability margin of any serial chain's frame position, for the volume engine.

`Reach(robot)` prepares the search of `kinematics.mechanisms.serial.search` for one frame:

* **joints that never move the point** (a zero position-Jacobian column at every probe, e.g. a
  wrist joint whose axis passes through the tool point) are held at a value in their range: they
  drop out of the search (`kinematics.mechanisms.serial.joint_box.setup`);
* **the mode**: planar (every axis parallel: task points in the arm's plane), revolved (the first
  joint turns a full turn about a fixed axis: the reachable set W is a solid of revolution, so
  the profile P = {(rho, z)} suffices and |W| = integral over P of 2 pi rho (Pappus)) or spatial;
* **seeds**: `samples` configurations drawn uniformly in the joint box (seeded: deterministic),
  their frame positions in a k-d tree over the task coordinates (the profile's (rho, z) when
  revolved, the base joint then set to bring the sample's azimuth onto the target's). A target's
  seeds are its `restarts` nearest samples, after the previous target's solution (warm start).

* **a fixed tool orientation** (`orientation`, `kinematics.mechanisms.serial.orientation`): the
  search matches the tool's direction(s) too (`kernels._residual`), every chain joint is searched
  (one that never moves the point still turns the tool), the samples are first descended onto the
  orientation alone (so the k-d tree holds points of the fixed-orientation set), and the set stays
  a solid of revolution only when the constraint is unchanged by the base's turn (a tool axis
  along the base axis); otherwise it is measured in space.

The margin of a target is tol - d + s, d the smallest distance found from it to f(joint box) and s
(>= 0, zero unless d <= tol) sigma_min(J) x the smallest joint slack at the solution, a local
estimate of the room around a reached point: positive exactly where some seed reached the target
to within `tol` = `REACH_TOL`, negative outside, -d + tol a true signed distance when the search
found the global minimum.

What the search can miss: a reachable target none of whose solutions any seed's descent reaches
(a thin part of W whose preimage no sample and no warm start lands in the basin of) is counted
outside -- a low bias. The volume's check run (`for_check`) uses twice the samples and restarts
and is compared with the first run like the half-step check.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from kinematics.generic.batched import compile_frame
from kinematics.inputs import task_points
from kinematics.mechanisms.orientation import ToolOrientation
from kinematics.mechanisms.serial import search as kernels
from kinematics.mechanisms.serial.joint_box import Setup, setup
from kinematics.mechanisms.serial.orientation import oriented_setup, reduced
from kinematics.mechanisms.serial.turn import partial_turn
from kinematics.model.robot import Robot

REACH_TOL = 1e-10
"""A target is reached when the search brings the frame within this distance [m]: the volume
engine locates the margin's sign change to 1e-12 m, so the boundary measured lies within
1e-10 m outside the true one (a relative bias below ~1e-9 for a metre-sized workspace)."""

ITERATIONS = 60
"""Levenberg-Marquardt steps per seed at most (a warm start needs a few, a far seed ~10-30)."""


FAR = 0.02
"""[m] A target whose first two descents (warm start, nearest sample) end farther than this from
it gets no more restarts: with tens of thousands of samples the nearest one lies within a few
millimetres of any reached point, so a target that far is outside; the restarts are spent where
the sign is at stake, near the boundary."""


SEARCHES = 10_000_000
"""The volume engine's budget in searches for the first run over the spatial margin
(`ReachMargin.search_budget`; each check run twice it; a first run that stops on it gets no
check run): each evaluation is a search with restarts, so the engine's `max_points` (2e8) bounds
nothing like the time. finger_edu converges at the defaults on 7.1e6 searches in its first run
and 1.3e7 in its check run, which this leaves room for; the wedge arm's first run stops on it
after 9.1e6 (~80 s of CPU)."""


SERIAL_BELOW = 512
"""Fewer targets than this are searched on one thread: starting a parallel region costs
milliseconds on a loaded machine (4-8 ms against 0.1 ms on one thread for 20 targets, load ~6 on
2 cores), and the volume engine's root refinement calls the margin with a few hundred points."""


@contextmanager
def _threads(n: int | None) -> Iterator[None]:
    """Numba kernels on `n` threads inside the block (None: as configured)."""
    import numba

    saved = numba.get_num_threads()
    if n is not None:
        numba.set_num_threads(min(n, saved))
    try:
        yield
    finally:
        numba.set_num_threads(saved)


@dataclass(frozen=True)
class Profile:
    """A solid of revolution for the volume engine: the (rho, z) profile's margin and box, the
    Pappus weight 2 pi rho of a column at rho, and the world box of a profile box."""

    margin: Callable[[np.ndarray], np.ndarray]
    lo: np.ndarray
    hi: np.ndarray
    axis: int
    origin: np.ndarray
    direction: np.ndarray
    turn: Any = None
    """A partial base turn's circle measure (`kinematics.mechanisms.serial.turn.TurnExtent`): the
    volume is then (L / 2 pi) x the solid's plus its integral over the profile; None: a full turn."""

    def weight(self, base: np.ndarray) -> np.ndarray:
        """2 pi rho [m] for columns at base (M, 1) = rho."""
        return 2.0 * math.pi * np.asarray(base)[:, 0]

    def world_box(self, box: np.ndarray) -> np.ndarray:
        """(2, 3) world box of the solid swept by a profile box (2, 2) [(rho, z) min, max]."""
        if not np.all(np.isfinite(box)):
            return np.full((2, 3), np.nan)
        rho = float(box[1, 0])
        ends = self.origin + np.outer(box[:, 1], self.direction)
        reach = rho * np.sqrt(np.clip(1.0 - self.direction**2, 0.0, 1.0))
        return np.stack([ends.min(axis=0) - reach, ends.max(axis=0) + reach])


class Reach:
    """The reachability search of `robot`'s frame (see the module docstring)."""

    def __init__(self, robot: Robot, frame: str | None = None, *, samples: int | None = None, restarts: int = 6,
                 seed: int = 0, orientation: ToolOrientation | None = None, revolve: bool = True) -> None:
        """revolve: False searches in 3-D even where the base turns (a full or partial turn): for
        margins the base's turn changes (obstacles, shapes fixed to the base)."""
        self.robot, self.frame, self.orientation, self.revolve = robot, frame, orientation, revolve
        self.kin = compile_frame(robot, frame)
        self.setup: Setup = setup(robot, self.kin, revolve)
        if orientation is not None:
            orientation = reduced(robot, self.kin, orientation, REACH_TOL, self.setup.reach)
            self.orientation = orientation
            self.setup = oriented_setup(robot, self.kin, self.setup, orientation, REACH_TOL)
        self.turn: tuple[float, float] | None = None
        if revolve:
            self.setup, self.turn = partial_turn(robot, self.kin, self.setup, orientation)
        # seeds a few millimetres apart over a plane or a profile, ~2 cm apart in space
        self.samples = samples or (200_000 if self.setup.mode == "spatial" else 40_000)
        self.restarts, self.seed = restarts, seed
        s, kin = self.setup, self.kin
        dof_of = {d.idx_v: i for i, d in enumerate(robot.dofs)}
        self.chain_dofs = np.array([dof_of[int(v)] for v in kin.idx_v])
        # chain bounds: searched joints their range (unbounded if periodic), the others held
        lo = s.base[self.chain_dofs].astype(float)
        hi = lo.copy()
        sampled = list(s.active)
        if s.mode == "revolved":
            sampled = [int(self.chain_dofs[0]), *sampled]
        rng_lo = dict(zip(s.active.tolist(), s.lo, strict=True))
        rng_hi = dict(zip(s.active.tolist(), s.hi, strict=True))
        per = dict(zip(s.active.tolist(), s.periodic, strict=True))
        self.searched = np.zeros(len(lo), bool)
        for k, dof in enumerate(self.chain_dofs):
            if int(dof) not in sampled:
                continue
            self.searched[k] = True
            if self.turn is not None and k == 0:
                lo[k], hi[k] = self.turn
            elif (s.mode == "revolved" and k == 0) or per.get(int(dof), False):
                lo[k], hi[k] = -np.inf, np.inf
            else:
                lo[k], hi[k] = rng_lo[int(dof)], rng_hi[int(dof)]
        self.lo, self.hi = lo, hi
        # the profile's search turns the base freely (the full turn's solid); a partial turn's
        # cover test holds it within +-(L - pi) of the antipode (`cover`)
        self.lo_free, self.hi_free = lo.copy(), hi.copy()
        self.lo_cover, self.hi_cover = lo.copy(), hi.copy()
        if self.turn is not None:
            slack = max(self.turn[1] - self.turn[0] - math.pi, 0.0)
            self.lo_free[0], self.hi_free[0] = -np.inf, np.inf
            self.lo_cover[0], self.hi_cover[0] = -slack, slack
        # W0: the set the rest of the chain reaches with the base held at 0 (`turn`)
        self.lo_base0, self.hi_base0 = lo.copy(), hi.copy()
        self.lo_base0[0] = self.hi_base0[0] = 0.0
        self.args = (kin.kind, kin.axis, kin.rotation, kin.translation, kin.frame_translation)
        if orientation is None:
            self.vec, self.dirs, self.scale = np.zeros((0, 3)), np.zeros((0, 3)), 0.0
        else:
            self.vec, self.dirs = orientation.vectors(kin.frame_rotation)
            self.scale = max(s.reach, 1e-3)  # [m per rad]: a direction error of 1 rad weighs like the arm's reach
        if s.mode == "revolved":
            d = s.axis_direction
            assert d is not None and s.axis_origin is not None
            e1 = np.cross(d, [1.0, 0.0, 0.0] if abs(d[0]) < 0.9 else [0.0, 1.0, 0.0])
            e1 /= np.linalg.norm(e1)
            self.basis = np.stack([e1, np.cross(d, e1), d])  # rows e1, e2, axis (right-handed)
            self.origin = np.asarray(s.axis_origin, dtype=float)

    @cached_property
    def checker(self) -> Reach:
        """The check run's search (`with_effort(2)`), built once."""
        return self.with_effort(2)

    def with_effort(self, factor: int) -> Reach:
        """The same search with `factor` x the samples and restarts."""
        return Reach(self.robot, self.frame, samples=factor * self.samples, restarts=factor * self.restarts,
                     seed=self.seed + 1, orientation=self.orientation, revolve=self.revolve)

    # -- geometry -------------------------------------------------------------------------------
    def chain_fk(self, Q: np.ndarray) -> np.ndarray:
        """(N, 3) frame positions at chain values Q (N, n) [rad or m]."""
        return kernels.chain_fk_many(np.ascontiguousarray(Q, dtype=float), *self.args)

    def _key(self, p: np.ndarray) -> np.ndarray:
        """Task coordinates the seeds are matched in: the profile (rho, z), the plane, or 3-D."""
        s = self.setup
        if s.mode == "revolved":
            v = (p - self.origin) @ self.basis.T
            return np.stack([np.hypot(v[:, 0], v[:, 1]), v[:, 2]], axis=1)
        if s.mode == "planar":
            return p[:, list(s.rows)]
        return p

    def _azimuth(self, p: np.ndarray) -> np.ndarray:
        v = (p - self.origin) @ self.basis.T
        return np.arctan2(v[:, 1], v[:, 0])

    @cached_property
    def _table(self) -> tuple[Any, np.ndarray, np.ndarray]:
        from scipy.spatial import cKDTree

        rng = np.random.default_rng(self.seed)
        lo = np.where(np.isfinite(self.lo), self.lo, -math.pi)
        hi = np.where(np.isfinite(self.hi), self.hi, math.pi)
        Q = lo + (hi - lo) * rng.random((self.samples, len(lo)))
        if self.orientation is not None:
            # seeds on the orientation: each sample descended to the tool directions alone (the
            # position's weight 0); where none gets there the set is empty and any seed will do
            Qp, ok = kernels.reach_all(np.zeros((len(Q), 3)), Q[:, None, :], self.lo, self.hi, *self.args, self.vec,
                                       self.dirs, self.scale, 0.0, REACH_TOL, ITERATIONS)
            Q = Qp[ok[:, 0], 0] if ok.any() else Q
        if self.setup.mode == "revolved":
            Q[:, 0] = 0.0  # (an axis along the base's is unchanged by the base's turn)
        P = self.chain_fk(Q)
        az = self._azimuth(P) if self.setup.mode == "revolved" else np.zeros(len(P))
        return cKDTree(self._key(P)), Q, az

    @cached_property
    def _fixed_base_table(self) -> Any:
        """A k-d tree over the seed table's frame positions in 3-D (revolved mode: the base at 0),
        for searches with the base held at 0 (W0 of `kinematics.mechanisms.serial.turn`), whose
        seeds must lie near the target itself, not only on its circle."""
        from scipy.spatial import cKDTree

        return cKDTree(self.chain_fk(self._table[1]))

    @cached_property
    def reach_centre(self) -> np.ndarray:
        """The first chain joint's origin (3,) [m], fixed in the world: the reach ball's centre."""
        return np.asarray(self.kin.translation[0], dtype=float)

    @cached_property
    def plane_point(self) -> np.ndarray:
        """A reached point (3,) [m]: its out-of-plane coordinate is the plane's for planar arms."""
        lo = np.where(np.isfinite(self.lo), self.lo, 0.0)
        hi = np.where(np.isfinite(self.hi), self.hi, 0.0)
        return self.chain_fk(0.5 * (lo + hi)[None])[0]

    # -- search ---------------------------------------------------------------------------------
    def distance(self, targets: np.ndarray, bounds: tuple[np.ndarray, np.ndarray] | None = None,
                 first_seed: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Margins (N,) [m] (see the module docstring) and best chain values (N, n) at world targets
        (N, 3), within the chain bounds `bounds` (default: the joint limits); `first_seed` (N, n):
        a seed tried before the samples' (after the warm start)."""
        targets = np.ascontiguousarray(targets, dtype=float)
        lo, hi = (self.lo, self.hi) if bounds is None else bounds
        # beyond the reach ball nothing is reached: its signed distance (<= minus the true
        # distance) saves the search there
        gap = np.linalg.norm(targets - self.reach_centre, axis=1) - self.setup.reach
        far = gap > 0
        if far.any():
            m = -gap
            q = np.full((len(targets), len(self.lo)), np.nan)
            if (~far).any():
                near = None if first_seed is None else first_seed[~far]
                m[~far], q[~far] = self.distance(targets[~far], (lo, hi), near)
            return m, q
        if first_seed is not None and self.setup.mode == "revolved" and lo[0] == hi[0] == 0.0:
            k = min(self.restarts, self.samples)  # the base held at 0: the nearest samples in 3-D
            _, idx = self._fixed_base_table.query(targets, k=k, workers=-1 if len(targets) > 20_000 else 1)
            seeds = self._table[1][np.asarray(idx).reshape(len(targets), k)]
        else:
            seeds = self._seeds(targets, lo, hi)
        if first_seed is not None:
            seeds = np.ascontiguousarray(np.concatenate([np.asarray(first_seed, float)[:, None, :], seeds], axis=1))
        with _threads(1 if len(targets) < SERIAL_BELOW else None):
            return kernels.search(targets, seeds, lo, hi, *self.args, self.vec, self.dirs, self.scale, REACH_TOL,
                                  ITERATIONS, kernels.CHUNK, FAR)

    def _seeds(self, targets: np.ndarray, lo: np.ndarray | None = None, hi: np.ndarray | None = None,
               count: int | None = None) -> np.ndarray:
        """(N, K, n) seeds of world targets (N, 3): the `count` (default `restarts`) nearest samples
        (module docstring), a revolved base's angle turned onto the target's azimuth and brought into
        [lo_0, hi_0]."""
        tree, Q, az = self._table
        k = min(count or self.restarts, len(Q))
        _, idx = tree.query(self._key(targets), k=k, workers=-1 if len(targets) > 20_000 else 1)
        idx = np.asarray(idx).reshape(len(targets), k)
        seeds = Q[idx]
        if self.setup.mode == "revolved":
            lo0, hi0 = (self.lo[0], self.hi[0]) if lo is None or hi is None else (lo[0], hi[0])
            mid = 0.5 * (lo0 + hi0) if math.isfinite(lo0) else 0.0
            turn = (self._azimuth(targets)[:, None] - az[idx] - mid + math.pi) % (2 * math.pi) - math.pi + mid
            seeds[:, :, 0] = np.clip(turn, lo0, hi0)
        return np.ascontiguousarray(seeds)

    def configurations(self, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The configurations reaching world targets (N, 3): chain values (N, K + 1, n) and whether
        each reaches its target within REACH_TOL (N, K + 1). Column 0 is the margin's own search
        (`distance`: a target is inside exactly where the volume's margin is >= 0); at the inside
        targets, columns 1 .. K are each of the K seeds descended to its end (`kernels.reach_all`)."""
        targets = np.ascontiguousarray(targets, dtype=float)
        K, n = min(self.restarts, self.samples), len(self.lo)
        Q = np.full((len(targets), K + 1, n), np.nan)
        ok = np.zeros((len(targets), K + 1), bool)
        m, Q[:, 0] = self.distance(targets)
        ok[:, 0] = m >= 0
        inside = np.flatnonzero(ok[:, 0])
        if len(inside):
            Q[inside, 1:], ok[inside, 1:] = self.solutions(targets[inside])
        return Q, ok

    def solutions(self, targets: np.ndarray, first: int = 0, count: int | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
        """Seeds `first` .. `first + count` (default: the `restarts` nearest samples) of world
        targets (N, 3), each descended to its end within the joint limits (`kernels.reach_all`, no
        early stop): chain values (N, K, n) and whether each reaches its target within REACH_TOL
        (N, K). A redundant arm's are K points of its self-motion set, a non-redundant arm's its
        distinct solutions whose basins hold a seed."""
        targets = np.ascontiguousarray(targets, dtype=float)
        return self.descend(targets, self._seeds(targets, count=first + (count or self.restarts))[:, first:])

    def descend(self, targets: np.ndarray, seeds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Seeds (N, K, n) of world targets (N, 3) each descended to its end within the joint
        limits: chain values (N, K, n) and whether each reaches its target within REACH_TOL (N, K)."""
        targets = np.ascontiguousarray(targets, dtype=float)
        with _threads(1 if len(targets) < SERIAL_BELOW else None):
            return kernels.reach_all(targets, np.ascontiguousarray(seeds, dtype=float), self.lo, self.hi, *self.args,
                                     self.vec, self.dirs, self.scale, 1.0, REACH_TOL, ITERATIONS)

    def jacobians(self, Q: np.ndarray) -> np.ndarray:
        """(..., 3, n) position Jacobians [m/rad or m/m] at chain values Q (..., n)."""
        Q = np.asarray(Q, dtype=float)
        flat = np.ascontiguousarray(np.nan_to_num(Q.reshape(-1, Q.shape[-1])))
        return kernels.chain_jacobian_many(flat, *self.args).reshape(*Q.shape[:-1], 3, Q.shape[-1])

    def task_jacobians(self, Q: np.ndarray) -> np.ndarray:
        """(..., 3, n) position Jacobians at chain values Q (..., n), restricted with a fixed
        orientation to the joint velocities that keep it: J N, the columns of N (n, n) an
        orthonormal basis of the null space of the held tool directions' Jacobian (singular values
        below 1e-9 x the largest, `kernels.chain_task_jacobian_many`), the others zero. Without an
        orientation, `jacobians`."""
        if self.orientation is None:
            return self.jacobians(Q)
        Q = np.asarray(Q, dtype=float)
        flat = np.ascontiguousarray(np.nan_to_num(Q.reshape(-1, Q.shape[-1])))
        F = kernels.chain_task_jacobian_many(flat, *self.args, self.vec)
        _, sv, Vh = np.linalg.svd(F[:, 3:, :])
        n = flat.shape[1]
        s = np.zeros((len(flat), n))
        s[:, :sv.shape[1]] = sv
        free = s <= 1e-9 * np.maximum(s[:, :1], 1e-300)  # (rows of Vh: sorted like the singular values)
        N = np.swapaxes(Vh, 1, 2) * free[:, None, :]
        return (F[:, :3, :] @ N).reshape(*Q.shape[:-1], 3, n)

    def world(self, points: np.ndarray) -> np.ndarray:
        """World targets (N, 3) of task points (N, d) (a planar arm's: in its plane)."""
        pts = np.asarray(points, dtype=float)
        if self.setup.mode != "planar":
            return pts
        world = np.tile(self.plane_point, (len(pts), 1))
        world[:, list(self.setup.rows)] = pts
        return world

    def margin(self, points: np.ndarray) -> np.ndarray:
        """(N, 1) margins [m] at task points (N, d)."""
        return self.distance(self.world(points))[0][:, None]

    def profile_world(self, points: np.ndarray) -> np.ndarray:
        """World points (N, 3) of profile points (N, 2) = (rho, z) (revolved mode: azimuth 0)."""
        pts = np.asarray(points, dtype=float)
        return self.origin + pts[:, :1] * self.basis[0] + pts[:, 1:2] * self.basis[2]

    def profile_of(self, targets: np.ndarray) -> np.ndarray:
        """Profile points (N, 2) = (rho, z) of world targets (N, 3) (revolved mode)."""
        return self._key(np.asarray(targets, dtype=float))

    def profile_search(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Margins (N,) [m] and chain values (N, n) at profile points (N, 2) = (rho, z) (revolved
        mode), the base turned freely (a partial turn's too: the full turn's solid)."""
        return self.distance(self.profile_world(points), (self.lo_free, self.hi_free))

    def profile_margin(self, points: np.ndarray) -> np.ndarray:
        """(N, 1) margins [m] at profile points (N, 2) = (rho, z) (`profile_search`)."""
        return self.profile_search(points)[0][:, None]

    def cover(self, points: np.ndarray, m: np.ndarray, q: np.ndarray) -> np.ndarray:
        """The cover test's margins (N,) [m] at profile points (N, 2) whose free-turn margins are m
        (N,) at chain values q (N, n): where m >= 0, the search for a second configuration whose
        base angle differs from q_0 by pi +- (L - pi) (L the base's range), i.e. of the point turned
        by -(q_0 + pi) about the axis with the base within +-(L - pi); elsewhere m. Where it is >= 0
        the arm with its base at 0 reaches two azimuths alpha, alpha' of the circle through the
        point with |alpha - alpha'| in [2 pi - L, pi], so the base's range turns them over the whole
        circle (`kinematics.mechanisms.serial.turn`: where it succeeds no circle sampling is needed)."""
        out = m.copy()
        hit = np.flatnonzero(m >= 0)
        if len(hit):
            th = -q[hit, 0] - math.pi
            rho, z = points[hit, 0], points[hit, 1]
            world = self.origin + (rho * np.cos(th))[:, None] * self.basis[0] + \
                (rho * np.sin(th))[:, None] * self.basis[1] + z[:, None] * self.basis[2]
            out[hit] = self.distance(world, (self.lo_cover, self.hi_cover))[0]
        return out

    def task_rank(self, probes: int = 64) -> int:
        """The largest rank (singular values above 1e-9 x the largest, or 1e-12) of the task
        Jacobian over the searched joints at `probes` of the seed table's configurations (on the
        fixed orientation's set with one): the number of freedoms the task point has. Below the
        task's dimension the reachable set has measure zero (the image of a map of lower rank
        everywhere, Sard); a probe of an analytic map sees the generic rank."""
        Q = self._table[1]
        Q = Q[np.linspace(0, len(Q) - 1, min(probes, len(Q))).astype(int)]
        J = self.task_jacobians(Q)[:, list(self.setup.rows) if self.setup.mode == "planar" else [0, 1, 2]]
        J = J[:, :, self.searched]
        if J.shape[2] == 0:
            return 0
        sv = np.linalg.svd(J, compute_uv=False)
        return int((sv > np.maximum(1e-9 * sv[:, :1], 1e-12)).sum(axis=1).max())

    def box(self) -> tuple[np.ndarray, np.ndarray]:
        """A task box [m] holding every reached point: the reach ball |p - p_1| <= R_1 (planar: its
        disc in the plane), with p_1 the first joint's origin and R_1 the distal lengths' sum."""
        s = self.setup
        c = self.reach_centre[list(s.rows)] if s.mode == "planar" else self.reach_centre
        return c - s.reach, c + s.reach


class ReachMargin:
    """`Reach.margin` as the volume engine's margin (task points; with `on_profile`, (rho, z) profile
    points): a callable with `profile` (a solid of revolution's, in revolved mode) and `for_check`
    (the search with twice the samples and restarts, for the engine's check run)."""

    def __init__(self, reach: Reach, on_profile: bool = False) -> None:
        self.reach, self.on_profile = reach, on_profile
        s = reach.setup
        self.profile: Profile | None = None
        # sampled 3-D columns of this margin stop on this many searches (a profile's are 2-D)
        self.search_budget: int | None = SEARCHES if s.mode == "spatial" else None
        if s.mode == "revolved" and not on_profile:
            R = s.reach
            turn = None
            if reach.turn is not None:
                from kinematics.mechanisms.serial.turn import TurnExtent

                turn = TurnExtent(reach)
            self.profile = Profile(ReachMargin(reach, True), np.array([0.0, -R]), np.array([R, R]), 1,
                                   reach.origin, reach.basis[2], turn)

    def __call__(self, points: np.ndarray) -> np.ndarray:
        # a user's call lands here (mechanism.margin()(points)): say what is wrong before the search
        s = self.reach.setup
        d = 2 if self.on_profile else len(s.rows) if s.mode == "planar" else 3
        pts = task_points(points, d)
        return self.reach.profile_margin(pts) if self.on_profile else self.reach.margin(pts)

    def for_check(self) -> ReachMargin:
        return ReachMargin(self.reach.checker, self.on_profile)

