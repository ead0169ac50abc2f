"""Assembling a closed-loop model: a configuration where every loop closes, found from a pose
that may not close (Gepetto's models are exported open at q = 0, with gaps of millimetres to most
of a metre).

`assemble(robot, values)` does what a user would do by hand, in three stages, and stops at the
first that closes every loop to `TOLERANCE` with every ranged joint within its range:

1. Newton on the passive joints from the start (the actuators held): a start that closes, or
   nearly, stays where it is — a sidecar's reference pose is kept, only polished (a start that
   closes to `OPEN_GAP` is kept even outside a range: it is the caller's pose; a pose the search
   finds is always within the ranges).
2. Projection: Gauss-Newton with minimum-norm steps on every joint that is not held (the nearest
   closed pose to first order), from the start clipped into the ranges; where that leaves a range,
   again with each step's joint values clipped into their ranges (projected Gauss-Newton).
3. Restarts: seeded random starts (each free joint uniform in its range; a joint with no range
   within half a turn, or for a prismatic joint the model's size, of its start value), each
   projected as in 2 with clipping; of the first `KEEP` that close within the ranges, the one nearest the
   start (in joint values) is kept.

What it cannot promise: a mechanism that has no closed configuration at the held values (an
actuator value outside the workspace) raises `AssemblyError`, and so does one whose closed set
the restarts never reach; the pose found is *a* closed pose near the start, not a chosen assembly
mode. Every result says where it came from (`Assembly.description`), so a report can say whether
it refers to `--q`, a sidecar reference or a pose found.
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from kinematics.errors import ConvergenceError
from kinematics.model.robot import Robot

if TYPE_CHECKING:  # pragma: no cover
    from kinematics.generic.closedloop import ClosedLoop

__all__ = ["TOLERANCE", "Assembly", "AssemblyError", "assemble"]

TOLERANCE = 1e-10
"""Largest loop-closure error [m, or rad for a 6D closure] of an assembled configuration. Newton
converges quadratically, so once within ~1e-6 the next step lands near 1e-14; 1e-10 leaves four
decades for the ill-conditioned closures of long legs."""

RANGE_TOL = 1e-9
"""A joint value counts as within its range up to this [rad or m] (Newton's rounding)."""

OPEN_GAP = 1e-9
"""A start whose closure error is at most this [m] counts as closed already (the batched solver's
threshold for a reference pose)."""

RESTARTS = 48
"""Random restarts at most (stage 3)."""

KEEP = 4
"""Stage 3 stops after this many closed poses within the ranges and keeps the nearest."""

MAX_ITER = 60
"""Gauss-Newton iterations per projection: from a start 1 m open, the steps of a well-posed
loop shrink to tolerance in 10-20 iterations; 60 leaves room for the backtracking of a poor start."""

Source = Literal["given", "sidecar reference", "neutral"]


class AssemblyError(ConvergenceError):
    """No configuration closing every loop was found from the given start."""


@dataclass(frozen=True)
class Assembly:
    """A closed configuration and where it came from.

    Attributes:
        q: Pinocchio configuration with every loop closed.
        values: one value per degree of freedom [rad or m].
        residual: largest closure error at q [m or rad].
        start_gap: largest closure error at the start [m or rad].
        source: where the start came from: values given by the caller (`--q`), the loop
            sidecar's `reference`, or the neutral pose q = 0.
        stage: 1 (Newton on the passive joints), 2 (projection) or 3 (restarts).
        held: names of the joints held at their start values.
        moved: largest change of a joint value from the start [rad or m].
    """

    q: np.ndarray
    values: np.ndarray
    residual: float
    start_gap: float
    source: Source
    stage: int
    held: tuple[str, ...]
    moved: float

    @property
    def found(self) -> bool:
        """True when the start did not close and the pose was searched for."""
        return self.start_gap > OPEN_GAP

    @property
    def description(self) -> str:
        """One phrase for reports: which pose an analysis refers to."""
        start = {"given": "the given joint values", "sidecar reference": "the sidecar's reference configuration",
                 "neutral": "the neutral pose (q = 0)"}[self.source]
        if not self.found:
            return start
        held = f", {', '.join(self.held)} held" if self.held else ""
        return (f"a closed pose found from {start} (closure gap {self.start_gap:.3g} there; joints moved by up "
                f"to {self.moved:.3g} rad or m{held})")


_DEFAULT: weakref.WeakKeyDictionary[Robot, Assembly] = weakref.WeakKeyDictionary()


def assemble(robot: Robot, values: Sequence[float] | np.ndarray | None = None, *,
             hold: Sequence[str] = (), seed: int = 0, loop: ClosedLoop | None = None, diagnose: bool = True,
             ranges: bool = True) -> Assembly:
    """A configuration of `robot` with every loop closed, found from `values` (module docstring).

    Args:
        robot: a robot with loop closures (sidecar or Gepetto `robot.yaml`).
        values: the start, one value per degree of freedom [rad or m]; default: the sidecar's
            `reference` where it gives one, else the neutral pose. The default's answer is cached
            per robot.
        hold: joints kept at their start values (e.g. the actuators at `--q`).
        seed: seed of the random restarts (the answer is deterministic for a fixed seed).
        loop: the robot's `ClosedLoop`, if the caller has one.
        diagnose: on failure, say why in the message: the closures left open at the closest pose,
            and whether the loops close with every closure a point, or with the ranges ignored
            (two more searches).
        ranges: False: the joint ranges are ignored (each joint's restarts within half a turn of
            its start); for that diagnosis.

    Raises:
        AssemblyError: no closed configuration within the ranges was found.
        UnknownJointError: `hold` names a joint the robot does not have.
        InvalidInputError: `values` of the wrong length or not finite.
    """
    from kinematics.errors import UnknownJointError
    from kinematics.generic.closedloop import ClosedLoop

    default = values is None and not hold and seed == 0 and ranges
    if default and robot in _DEFAULT:
        return _DEFAULT[robot]
    loop = loop or ClosedLoop(robot)
    names = robot.joint_names
    for h in hold:
        if h not in names:
            raise UnknownJointError(h, names)
    source: Source
    if values is not None:
        start, source = robot.joint_values(values), "given"
    else:
        start = np.zeros(robot.nv)
        for name, value in loop.spec.reference.items():
            start[names.index(name)] = value
        source = "sidecar reference" if loop.spec.reference else "neutral"
    q0 = robot.configuration(start)
    e0, _ = loop.residual(q0)
    gap = float(np.max(np.abs(e0))) if e0.size else 0.0
    held_dofs = [names.index(h) for h in hold]
    free_dofs = np.array([i for i in range(robot.nv) if i not in held_dofs], dtype=int)
    free_v = np.array([robot.dofs[i].idx_v for i in free_dofs], dtype=int)
    lo, hi = (robot.lower, robot.upper) if ranges else (np.full(robot.nv, -np.inf), np.full(robot.nv, np.inf))
    angular = _angular(robot)

    def nearest_turn(v: np.ndarray) -> np.ndarray:
        # whole turns of a revolute joint are the same pose: each angle at the winding nearest its
        # start, then a turn into its range where that fits; "moved" then measures the motion,
        # not the windings of the Newton path
        w = start + _wrapped(robot, v - start)
        w = np.where(angular & (w < lo) & (w + 2 * np.pi <= hi + RANGE_TOL), w + 2 * np.pi, w)
        return np.where(angular & (w > hi) & (w - 2 * np.pi >= lo - RANGE_TOL), w - 2 * np.pi, w)

    def within(v: np.ndarray) -> bool:
        w = nearest_turn(v)
        return bool(np.all((w >= lo - RANGE_TOL) & (w <= hi + RANGE_TOL)))

    def result(q: np.ndarray, err: float, stage: int) -> Assembly:
        v = nearest_turn(robot.values_from_configuration(q))
        a = Assembly(robot.configuration(v), v, err, gap, source, stage, tuple(hold),
                     float(np.max(np.abs(v - start), initial=0.0)))
        if default:
            _DEFAULT[robot] = a
        return a

    # 1: the passive joints only (a start that closes stays put)
    passive_free = np.array([v for v in loop.passive_v if v in set(free_v.tolist())], dtype=int)
    q, err, _ = loop.newton(q0, TOLERANCE, MAX_ITER, free=passive_free)
    if err <= TOLERANCE and (gap <= OPEN_GAP or within(robot.values_from_configuration(q))):
        return result(q, err, 1)  # a start that closes is the caller's pose, ranges or not
    # 2: projection over every free joint
    for clip in (False, True):
        q, err = _project(loop, robot.configuration(np.clip(start, lo, hi)), free_v, clip, lo, hi)
        if err <= TOLERANCE and within(robot.values_from_configuration(q)):
            return result(q, err, 2)
    # 3: seeded restarts, the nearest closed pose kept
    rng = np.random.default_rng(seed)
    scale = _size(robot, q0)
    span = np.array([np.pi if d.kind != "prismatic" else scale for d in robot.dofs])
    r_lo = np.where(np.isfinite(lo), lo, start - span)
    r_hi = np.where(np.isfinite(hi), hi, start + span)
    best: tuple[float, np.ndarray, float] | None = None
    kept = 0
    closest = (err, q)
    for _ in range(RESTARTS):
        v = start.copy()
        v[free_dofs] = rng.uniform(r_lo[free_dofs], r_hi[free_dofs])
        q, err = _project(loop, robot.configuration(v), free_v, True, lo, hi)
        closest = min(closest, (err, q), key=lambda c: c[0])
        vals = robot.values_from_configuration(q)
        if err > TOLERANCE or not within(vals):
            continue
        d = float(np.linalg.norm(nearest_turn(vals) - start))
        if best is None or d < best[0]:
            best = (d, q, err)
        kept += 1
        if kept >= KEEP:
            break
    if best is not None:
        return result(best[1], best[2], 3)
    what = {"given": "the given joint values", "sidecar reference": "the sidecar's reference configuration",
            "neutral": "the neutral pose (q = 0)"}[source]
    held = f" with {', '.join(hold)} held" if hold else ""
    why = _diagnosis(robot, loop, closest[1], start, tuple(hold), seed) if diagnose else ""
    raise AssemblyError(f"assembling {robot.name} from {what}{held} (closure gap {gap:.3g} there; "
                        f"projection and {RESTARTS} random restarts found no closed pose within the joint ranges"
                        f"{why})", MAX_ITER, closest[0], TOLERANCE)


def _diagnosis(robot: Robot, loop: ClosedLoop, q: np.ndarray, start: np.ndarray, hold: tuple[str, ...],
               seed: int) -> str:
    """Why no closed pose was found, for the error message: the closures the closest pose leaves
    open (position [m] and orientation [rad] apart), and two searches a user would try next: the
    6D closures taken as points (their frames' orientations free), and the joint ranges ignored."""
    import dataclasses

    e, _ = loop.residual(q)
    open_, k = [], 0
    for c in loop.spec.closures:
        part = e[k:k + c.size]
        k += c.size
        lin = float(np.linalg.norm(part[:3]))
        ang = float(np.linalg.norm(part[3:])) if c.size == 6 else 0.0
        if max(lin, ang) > TOLERANCE:
            open_.append(f"{c.name} ({lin:.2g} m" + (f", {ang:.2g} rad" if c.size == 6 else "") + ")")
    parts = [f"; the closest pose found leaves {len(open_)} of {len(loop.spec.closures)} closures open: "
             + ", ".join(open_[:4]) + (", ..." if len(open_) > 4 else "")]
    if any(c.size == 6 for c in loop.spec.closures):
        spec = loop.spec
        points = dataclasses.replace(robot, loops=dataclasses.replace(
            spec, closures=tuple(dataclasses.replace(c, type="point") for c in spec.closures)))
        try:
            assemble(points, start, hold=hold, seed=seed, diagnose=False)
            parts.append("; with every closure a point (`3d`: the paired frames' orientations free) it closes, "
                         "so the 6D closures' frame orientations are what cannot be matched")
        except AssemblyError:
            parts.append("; it does not close with every closure a point either")
    if np.isfinite(robot.lower).any() or np.isfinite(robot.upper).any():
        try:
            a = assemble(robot, start, hold=hold, seed=seed, diagnose=False, ranges=False)
            _, K = loop.residual(a.q)
            # the joints the loops depend on there, outside their ranges (a joint outside every loop
            # was only moved by a restart)
            out = [d.name for d, x in zip(robot.dofs, a.values, strict=True)
                   if (x < d.lower - RANGE_TOL or x > d.upper + RANGE_TOL) and np.any(K[:, d.idx_v] != 0.0)]
            parts.append(f"; ignoring the joint ranges it closes, with {', '.join(out[:6])}"
                         + (", ..." if len(out) > 6 else "") + (" outside their ranges" if len(out) > 1 else " outside its range")
                         if out else
                         "; ignoring the joint ranges it closes at a pose within them that the restarts missed")
        except AssemblyError:
            parts.append("; ignoring the joint ranges it does not close either")
    return "".join(parts)


def _angular(robot: Robot) -> np.ndarray:
    return np.array([d.kind != "prismatic" for d in robot.dofs])


def _wrapped(robot: Robot, dv: np.ndarray) -> np.ndarray:
    """Joint-value differences with revolute ones wrapped to [-pi, pi)."""
    return np.where(_angular(robot), (dv + np.pi) % (2 * np.pi) - np.pi, dv)


def _project(loop: ClosedLoop, q: np.ndarray, free_v: np.ndarray, clip: bool, lo: np.ndarray, hi: np.ndarray
             ) -> tuple[np.ndarray, float]:
    """Gauss-Newton from `q` on the velocity indices `free_v`: minimum-norm steps, a step halved
    while the residual grows; with `clip`, the joint values clipped into [lo, hi] after each
    step (projected Gauss-Newton). Returns (q, largest closure error)."""
    import pinocchio as pin

    robot = loop.robot

    def clipped(qq: np.ndarray) -> np.ndarray:
        v = robot.values_from_configuration(qq)
        return qq if not clip or np.all((v >= lo) & (v <= hi)) else robot.configuration(np.clip(v, lo, hi))

    e, K = loop.residual(q)
    err = float(np.max(np.abs(e))) if e.size else 0.0
    for _ in range(MAX_ITER):
        if err <= TOLERANCE:
            break
        dv = -np.linalg.lstsq(K[:, free_v], e, rcond=None)[0]
        step = 1.0
        while step >= 1e-3:
            v = np.zeros(robot.model.nv)
            v[free_v] = step * dv
            q_new = clipped(pin.integrate(robot.model, q, v))
            e_new, K_new = loop.residual(q_new)
            err_new = float(np.max(np.abs(e_new)))
            if err_new < err:
                break
            step *= 0.5
        if not err_new < err:
            break  # stalled (a local minimum of the gap, or the ranges block the way)
        q, e, K, err = q_new, e_new, K_new, err_new
    return q, err


def _size(robot: Robot, q: np.ndarray) -> float:
    """The model's size [m]: the largest distance between two joint origins at q (>= 1 mm)."""
    import pinocchio as pin

    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    pts = np.array([data.oMi[j].translation for j in range(1, robot.model.njoints)])
    if len(pts) < 2:
        return 1e-3
    return max(float(np.max(np.linalg.norm(pts[:, None] - pts[None], axis=-1))), 1e-3)

