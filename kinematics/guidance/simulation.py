"""Simulated operators, fixed-step simulation of the guidance controller, and paper A's three
experiments as ready scenarios (with the same pushes without the virtual impedance as baseline).

Operators are force sources through a one-axis compression load cell (they push, never pull):

* `Profile`: a scripted force - pulse, step or ramp - along a fixed direction;
* `ReactiveOperator`: pushes (ramping up), and once the felt impedance K_v has exceeded
  `feel` for a reaction delay, lets go (ramping down) - paper A's experiment 2;
* `StubbornOperator`: keeps pushing whatever it feels until a given time - experiment 3.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from kinematics.errors import InvalidInputError
from kinematics.guidance.controller import Controller, GuidanceParams, Kinematics, ScaraKinematics, Step
from kinematics.sizes import MAX_STEPS, check_points

SINGULAR_RADIUS = 0.01
"""A run *reached the singularity* when the smaller radius fell below this [m] (1/70 of the
SCARA's reach; on the SCARA, |theta2| < ~0.03 rad)."""


def _direction(v: Any, dim: int) -> np.ndarray:
    d = np.asarray(v, dtype=float)
    if d.shape != (dim,) or not np.all(np.isfinite(d)) or not np.any(d):
        raise InvalidInputError("direction", f"need {dim} finite components, not all zero, got {v!r}")
    return d / np.linalg.norm(d)


def _check_magnitude(m: float) -> None:
    if not (isinstance(m, (int, float)) and math.isfinite(m) and m >= 0):
        raise InvalidInputError("force", f"must be a finite magnitude >= 0 [N] (a load cell only pushes), got {m}")


def _check_time(name: str, t: float, *, positive: bool = False, finite: bool = True) -> None:
    ok = isinstance(t, (int, float)) and not math.isnan(t) and (math.isfinite(t) or not finite)
    if not ok or (t <= 0 if positive else t < 0):
        raise InvalidInputError(name, f"must be a {'finite ' if finite else ''}time {'> 0' if positive else '>= 0'} "
                                f"[s], got {t}")


@dataclass(frozen=True)
class Profile:
    """Scripted push of `magnitude` [N] along `direction`.

    kind: "pulse" (on from t0 to t1), "step" (on from t0; t1 unused), "ramp" (0 at t0 to full at
    t1, then held; t1 = t0 is a step at t0; a ramp needs a finite t1).
    """

    kind: Literal["pulse", "step", "ramp"]
    direction: tuple[float, ...]
    magnitude: float
    t0: float
    t1: float = math.inf

    def __post_init__(self) -> None:
        if self.kind not in ("pulse", "step", "ramp"):
            raise InvalidInputError("kind", f"pulse, step or ramp; got {self.kind!r}")
        _check_magnitude(self.magnitude)
        _check_time("t0", self.t0)
        _check_time("t1", self.t1, finite=self.kind == "ramp")
        if self.t1 < self.t0:
            raise InvalidInputError("t1", f"must be >= t0 = {self.t0} s, got {self.t1}")

    def __call__(self, t: float, last: Step | None) -> float:
        if t < self.t0:
            return 0.0
        if self.kind == "pulse":
            return self.magnitude if t < self.t1 else 0.0
        if self.kind == "ramp" and t < self.t1:
            return self.magnitude * (t - self.t0) / (self.t1 - self.t0)
        return self.magnitude


@dataclass
class ReactiveOperator:
    """Pushes with `magnitude` [N] (ramped over `rise` s from t0); once K_v > `feel` [N/m] has
    lasted `delay` s, lets go over `rise` s."""

    direction: tuple[float, ...]
    magnitude: float
    t0: float = 1.0
    rise: float = 0.3
    feel: float = 0.5 * 250.0
    delay: float = 0.25
    felt_since: float | None = field(default=None, init=False)
    release_at: float | None = field(default=None, init=False)

    def __post_init__(self) -> None:
        _check_magnitude(self.magnitude)
        _check_time("t0", self.t0)
        _check_time("rise", self.rise, positive=True)
        _check_time("delay", self.delay)
        if not (math.isfinite(self.feel) and self.feel >= 0):
            raise InvalidInputError("feel", f"must be a finite stiffness >= 0 [N/m], got {self.feel}")

    def reset(self) -> None:
        """Forget what was felt: `simulate` calls this first, so one operator serves many runs."""
        self.felt_since = None
        self.release_at = None

    def __call__(self, t: float, last: Step | None) -> float:
        if last is not None and last.k_v > self.feel:
            if self.felt_since is None:
                self.felt_since = t
            if self.release_at is None and t - self.felt_since >= self.delay:
                self.release_at = t
        elif self.release_at is None:
            self.felt_since = None
        if t < self.t0:
            return 0.0
        level = min(1.0, (t - self.t0) / self.rise)
        if self.release_at is not None:
            level = min(level, max(0.0, 1.0 - (t - self.release_at) / self.rise))
        return self.magnitude * level


@dataclass
class StubbornOperator:
    """Pushes with `magnitude` [N] from t0 (ramped over `rise` s) until `until`, whatever K_v."""

    direction: tuple[float, ...]
    magnitude: float
    t0: float = 1.0
    until: float = 6.0
    rise: float = 0.3

    def __post_init__(self) -> None:
        _check_magnitude(self.magnitude)
        _check_time("t0", self.t0)
        _check_time("rise", self.rise, positive=True)
        _check_time("until", self.until, finite=False)

    def __call__(self, t: float, last: Step | None) -> float:
        if t < self.t0:
            return 0.0
        up = min(1.0, (t - self.t0) / self.rise)
        down = min(1.0, max(0.0, 1.0 - (t - self.until) / self.rise))
        return self.magnitude * min(up, down)


Operator = Callable[[float, Step | None], float]


@dataclass(frozen=True)
class Run:
    """A recorded simulation, one row per control step (SI units)."""

    t: np.ndarray
    force: np.ndarray
    x: np.ndarray
    v_raw: np.ndarray
    v: np.ndarray
    radii: np.ndarray
    k_v: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    saturated: np.ndarray
    blocked: np.ndarray
    params: GuidanceParams
    planar: bool
    first_refusal: str | None = None
    """Why the controller first held the arm (`Step.reason`), if it ever did."""

    def summary(self) -> dict[str, Any]:
        """The issue's stable keys (SI units)."""
        speed = np.linalg.norm(self.v, axis=1)
        out = {
            "max_speed": float(speed.max()),
            "max_raw_speed": float(np.linalg.norm(self.v_raw, axis=1).max()),
            "saturated_seconds": float(self.saturated.sum() * self.params.dt),
            "saturated_intervals": _intervals(self.t, self.saturated),
            "min_radius": float(self.radii[:, 0].min()),
            "final_position": self.x[-1].tolist(),
            "min_abs_theta2": float(np.abs(self.q[:, 1]).min()) if self.planar else None,
            "peak_joint_speed": float(np.abs(self.qdot).max()),
            "reached_singularity": bool(self.radii[:, 0].min() < SINGULAR_RADIUS),
            "max_k_v": float(self.k_v.max()),
            "blocked_steps": int(self.blocked.sum()),
            "first_refusal": self.first_refusal,
            "virtual_impedance": self.params.virtual_impedance,
        }
        return out

    def to_csv(self) -> str:
        dim = self.x.shape[1]
        axes = "xyz"[:dim]
        cols = (["t"] + [f"F{a}" for a in axes] + list(axes) + [f"v_raw_{a}" for a in axes] + [f"v_{a}" for a in axes]
                + [f"r{k + 1}" for k in range(self.radii.shape[1])] + ["K_v"]
                + [f"q{k + 1}" for k in range(self.q.shape[1])] + [f"qdot{k + 1}" for k in range(self.qdot.shape[1])]
                + ["saturated", "blocked"])
        data = np.column_stack([self.t, self.force, self.x, self.v_raw, self.v, self.radii, self.k_v, self.q, self.qdot,
                                self.saturated, self.blocked])
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(cols)
        for row in data:
            w.writerow([repr(float(v)) for v in row])
        return buf.getvalue()


def _intervals(t: np.ndarray, flag: np.ndarray) -> list[list[float]]:
    """[[start, end], ...] of the runs where flag is True [s]."""
    if not flag.any():
        return []
    f = np.concatenate([[False], flag, [False]]).astype(np.int8)
    starts = np.flatnonzero(np.diff(f) == 1)
    ends = np.flatnonzero(np.diff(f) == -1) - 1
    return [[float(t[a]), float(t[b])] for a, b in zip(starts, ends, strict=True)]


def simulate(kin: Kinematics, params: GuidanceParams, q0: np.ndarray, operator: Operator,
             direction: Any, duration: float) -> Run:
    """Run the controller at 1/dt Hz for `duration` s against an operator."""
    if not (math.isfinite(duration) and duration > 0):
        raise InvalidInputError("duration", f"must be positive [s], got {duration}")
    d = _direction(direction, kin.dim)
    ctrl = Controller(kin, params, np.asarray(q0, dtype=float))
    reset = getattr(operator, "reset", None)
    if reset is not None:  # stateful operators start each run afresh
        reset()
    n = check_points("dt", round(duration / params.dt), limit=MAX_STEPS, unit="control steps",
                     hint=f"{duration:g} s at dt = {params.dt:g} s")
    dim, nq, nv = kin.dim, len(ctrl.q), len(kin.rate(ctrl.q, ctrl.q, params.dt))  # nv < nq: continuous joints
    rec = {k: np.empty((n, dim)) for k in ("force", "x", "v_raw", "v")}
    radii, k_v = np.empty((n, dim)), np.empty(n)
    q, qdot = np.empty((n, nq)), np.empty((n, nv))
    sat, blk = np.zeros(n, bool), np.zeros(n, bool)
    t = np.arange(n) * params.dt
    last: Step | None = None
    refusal: str | None = None
    for i in range(n):
        f = d * operator(float(t[i]), last)
        last = ctrl.step(f)
        rec["force"][i], rec["x"][i], rec["v_raw"][i], rec["v"][i] = f, last.x, last.v_raw, last.v
        radii[i], k_v[i], q[i], qdot[i] = last.radii, last.k_v, last.q, last.qdot
        sat[i], blk[i] = last.saturated, last.blocked
        if refusal is None and last.reason is not None:
            refusal = last.reason
    return Run(t, rec["force"], rec["x"], rec["v_raw"], rec["v"], radii, k_v, q, qdot, sat, blk, params, dim == 2,
               refusal)


# -- paper A's experiments ----------------------------------------------------------------------
@dataclass(frozen=True)
class Experiment:
    """A ready scenario: start, push direction, operator, duration, and what it reproduces."""

    number: int
    title: str
    start: tuple[float, float]
    direction: tuple[float, float]
    duration: float
    make_operator: Callable[[GuidanceParams, float | None], Operator]


EXPERIMENTS: dict[int, Experiment] = {
    1: Experiment(1, "hard short push: the velocity saturates, no radius falls below 0.1 m",
                  (0.5, 0.4), (0.0, -1.0), 6.0, lambda p, f: Profile("pulse", (0.0, -1.0), 30.0 if f is None else f, 2.0, 4.5)),
    2: Experiment(2, "push +x towards (0.7, 0); the operator feels the virtual wall and stops",
                  (0.4, 0.0), (1.0, 0.0), 8.0, lambda p, f: ReactiveOperator((1.0, 0.0), 6.0 if f is None else f, feel=0.5 * p.k_max)),
    3: Experiment(3, "push +x towards (0.7, 0) and keep pushing; the robot never becomes singular",
                  (0.4, 0.0), (1.0, 0.0), 9.0, lambda p, f: StubbornOperator((1.0, 0.0), 6.0 if f is None else f, until=6.0)),
}


def run_experiment(number: int, sp: Any, params: GuidanceParams | None = None, force: float | None = None) -> Run:
    """Simulate one of paper A's experiments on a planar arm (ScaraParams), elbow 'up' at the start.

    Args:
        force: the operator's push [N] (default: 30 N for experiment 1, 6 N for 2 and 3).
    """
    from kinematics.errors import UnknownChoiceError
    from kinematics.mechanisms.scara.closed_form import ik

    if isinstance(number, bool) or not isinstance(number, int):  # "1" would be told "did you mean '1'?"
        raise InvalidInputError("number", f"an experiment number is an int ({', '.join(map(str, EXPERIMENTS))}), "
                                          f"got {number!r}")
    if number not in EXPERIMENTS:
        raise UnknownChoiceError(str(number), [str(k) for k in EXPERIMENTS])
    ex = EXPERIMENTS[number]
    params = params or GuidanceParams()
    sol = ik(sp, np.array(ex.start))
    ok = np.flatnonzero(sol.within_limits)
    if not len(ok):
        raise InvalidInputError("start", f"{ex.start} is not reachable within the joint limits")
    return simulate(ScaraKinematics(sp), params, sol.q[ok[0]], ex.make_operator(params, force), ex.direction, ex.duration)
