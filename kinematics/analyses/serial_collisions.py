"""Collision-aware reach of a serial arm: whether some configuration within the joint limits puts
the tool at a target with every checked pair apart.

At a task point x the margin is

    m(x) = k(x)                              where k(x) <= 0 (no configuration reaches x),
    m(x) = min(k(x), max over c in C(x) of min over pairs p of d_p(q_c))   elsewhere,

k the reachability margin (`kinematics.mechanisms.serial.reach`: tol - distance found + a local
room estimate, > 0 exactly where the search reaches x), C(x) the configurations the search found
reaching x and d_p the signed distance of pair p [m] (`kinematics.generic.capsules`: closed forms
for capsules, spheres, plates and half-spaces, coal for boxes and meshes; only signs need be
right). m > 0 exactly where a found configuration reaches x with every pair apart, so the column
engine locates its sign changes like any margin's. The union is this margin (an arm has one
branch); each watched pair's target is the same with that pair alone (its own best configuration).

C(x): first the margin's own search's solution (a warm start along the column, then the nearest
samples); where some pair is negative there, each of the `restarts` seeds descended to its end
(`Reach.solutions`), the reaching ones added; where all of those collide, the next
(ESCALATE - 1) x `restarts` nearest samples' descents too. A non-redundant arm (3 joints for a
3-D point) has finitely many solutions (elbow up / down, shoulder left / right): the restarts find
those whose basins hold a seed. A redundant arm (more searched joints than task coordinates, 6
or 7 for a 3-D point) has a self-motion set of dimension n - 3 through each solution; the restarts
give up to ESCALATE x `restarts` + 1 points of it. Where all of them collide, the best one takes up
to ESCAPE_STEPS null-space steps away from contact: the binding pair's gradient g (forward
differences of its distance, `AnalyticDistances.pair_distances`) projected onto the null space
of the position Jacobian J, s = (I - J+ J) g, a Newton step of that distance to
ESCAPE_CLEARANCE along s (at most ESCAPE_ANGLE), then a descent back onto the target; a step is
kept where the smallest distance grows, and the steps go on while it is still negative (not
with a fixed tool orientation).

What it can miss (a low bias of the collision-free set, as the kinematic search's): a point whose
only collision-free configurations lie in no found basin or, for a redundant arm, in a part of the
self-motion set none of the descents ends in and the null-space steps (local: they follow one
pair's gradient, and another pair may bind after a step) do not reach. The volume's check run
(`for_check`) repeats the measurement with twice the samples and restarts (and half the step):
where more configurations free more of the workspace the two runs disagree, the difference enters
the error estimate and marks the run not converged when it exceeds the estimates.

The base's turn: a pair of bodies both carried by a full-turn base joint keeps its distances
when the base turns (the whole pair turns rigidly), and so does a pair with a fixed body the turn
leaves as it is (a floor, a post on the axis: `turn_envelope.coaxial`); with only such pairs the
collision-free set is still a solid of revolution and is measured on its (rho, z) profile (Pappus),
at azimuth 0. A pair with another body fixed to the world (the base link, an obstacle) changes with
the base's angle: a volume then brackets it on the profile (`serial_margin`, `Turn`: the body's turn
envelope below, its pairs left out above) where the bracket meets the tolerance; otherwise (and for
a base that turns through less than a full turn) the arm is searched and measured in 3-D
(`Reach(revolve=False)`), with the pre-scan's cells (`kinematics.analyses.collision_prescan`) on
the 3-D grid.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from kinematics.analyses.collision_prescan import Prescan
from kinematics.errors import InvalidInputError, KinematicsWarning, UnsupportedRobotError
from kinematics.generic.batched import configurations
from kinematics.generic.capsules import AnalyticDistances
from kinematics.mechanisms.base import UNION, Mechanism
from kinematics.mechanisms.serial.reach import Reach, ReachMargin
from kinematics.sizes import MAX_COLLISION_VIEW_POINTS

if TYPE_CHECKING:
    from kinematics.analyses.collisions import GridCounts
    from kinematics.analyses.columns import ColumnVolume
    from kinematics.generic.collision import CollisionModel
    from kinematics.generic.turn_envelope import TurnEnvelope

ESCALATE = 4
"""Where every restart's configuration collides, the next (ESCALATE - 1) x `restarts` nearest
samples are descended too (the ur5 near its base: 99 of 392 grid points colliding with the 6
restarts, 37 with 24, 32 with 96)."""


SEARCHES = 1_000_000
"""The volume engine's budget for a collision-aware margin searched in 3-D (`search_budget`, as
`reach.SEARCHES` for the kinematic one; each check run twice it, a first run that stops on it gets
no check run): an evaluation here is a search plus every pair's distance at its configurations,
~0.2 ms on the ur5's 20 mesh pairs through coal (one core) against ~0.01 ms for a search
alone, so the kinematic budget of 10^7 would be hours. 10^6 keeps the benchmark's ur5 run (step
0.1 m, rtol 0.1: 1.08e6 evaluations with its check run) converging; it bounds every run, but at
the CLI's defaults (1 cm, rtol 1e-3) the ur5 (in 3-D: its base link's turn envelope brackets too
wide a volume, `Turn`) stops on it after 15 minutes with 3.575 +- 3.7 m^3,
and where a run stops its error estimate is no use (a budget of 10^5 at step 0.02 m: 3.62 +- 7.1
m^3, 106 s): a larger --step / --rtol is the way to an answer."""


ESCAPE_STEPS = 4
"""Null-space steps a redundant arm takes away from contact where every configuration found collides."""

ESCAPE_H = 1e-5
"""[rad or m] Forward-difference step of the binding pair's gradient."""

ESCAPE_ANGLE = 0.3
"""[rad] Largest null-space step (before the descent back onto the target)."""

ESCAPE_CLEARANCE = 0.005
"""[m] The binding pair's distance a step aims at (its linear model's)."""

SAME_CONFIGURATION = 1e-8
"""[rad or m] Restarts' solutions whose chain values round to the same multiple of this are one
configuration, their distances evaluated once (`SerialCollisionMargin.distinct_distances`). A
non-redundant arm's restarts descend to its few inverse-kinematics solutions: finger_edu at
colliding points, 24 descents end at 1.5 distinct configurations at 1e-8 rad (22 at 1e-12, 3.3 at
1e-9: the descents' own spread), so 16x fewer coal calls there; a redundant arm's (ur5, panda)
are all distinct. A pair's distance moves at most ~(arm's reach) x 1e-8 m between two such."""


def carried_joints(robot: Any, reach: Reach) -> set[int]:
    """The joints the first chain joint (the base joint) carries: its subtree of the kinematic tree."""
    model = robot.model
    first = next(j for j in range(1, model.njoints) if model.joints[j].idx_v == int(reach.kin.idx_v[0]))
    return set(model.subtrees[first])


def _setup_configuration(robot: Any, reach: Reach) -> np.ndarray:
    """(nq,) the configuration with every joint at the search setup's values (the joints off the
    chain stay there: bodies the base joint does not carry are fixed at it)."""
    return configurations(robot, np.asarray(reach.setup.base, dtype=float)[None, :])[0]


def turn_invariant(robot: Any, distances: AnalyticDistances, reach: Reach) -> bool:
    """Whether every checked pair keeps its distances when the first chain joint turns: both of
    its bodies are carried by that joint (in its subtree of the kinematic tree) or neither is, or
    the one not carried is unchanged by turns about the joint's axis (`turn_envelope.coaxial`: a
    floor's half-space, a coaxial cylinder)."""
    import pinocchio as pin

    from kinematics.generic.turn_envelope import coaxial

    carried = carried_joints(robot, reach)
    geometry = distances.model.geometry
    objs = geometry.geometryObjects
    placed = None
    for a, b in distances.model.pairs:
        ca, cb = int(objs[a].parentJoint) in carried, int(objs[b].parentJoint) in carried
        if ca == cb:
            continue
        if reach.setup.mode != "revolved":
            return False
        if placed is None:  # the fixed bodies' world placements (off-chain joints at the setup's values)
            placed = pin.GeometryData(geometry)
            pin.updateGeometryPlacements(robot.model, robot.model.createData(), geometry, placed,
                                         _setup_configuration(robot, reach))
        k = b if ca else a
        if not coaxial(objs[k].geometry, placed.oMg[k], reach.origin, reach.basis[2]):
            return False
    return True


def collision_reach(mech: Mechanism, robot: Any, distances: AnalyticDistances) -> Reach:
    """The search a collision-aware margin of `mech` (one with `reach_search`, a serial arm, else
    UnsupportedRobotError) uses: its own when the checked pairs are unchanged by the base's full
    turn (module docstring), else one in 3-D."""
    if "reach_search" not in mech.capabilities:
        raise UnsupportedRobotError(mech.name, "a serial arm's collision margin is for open chains searched by "
                                               "their reach search")
    reach = mech.reach_search()
    if reach.setup.mode == "revolved" and (reach.turn is not None or not turn_invariant(robot, distances, reach)):
        return Reach(robot, reach.frame, restarts=reach.restarts, seed=reach.seed, orientation=reach.orientation,
                     revolve=False)
    return reach


Turn = Literal["auto", "envelope", "spatial"]
"""How a collision-aware volume treats pairs a full-turn base's turn changes (a body fixed in the
world against a carried one): "envelope" measures the profile twice in one run, with each fixed
body replaced by its turn envelope (a lower bound) and without its pairs (an upper bound),
"spatial" measures in 3-D, "auto" measures the bracket where its width estimated on the
pre-scan's grid meets the tolerance, and in 3-D otherwise or where the measured bracket still
misses it (`kinematics.analyses.collision_volume.measure_collision_workspace`)."""


def serial_margin(mech: Mechanism, robot: Any, model: CollisionModel, distances: AnalyticDistances,
                  turn: Turn = "auto") -> tuple[SerialCollisionMargin, TurnEnvelope | None]:
    """The collision-aware margin of a serial arm for a volume, and the turn envelope it uses
    (None: it measures `model`'s own pairs, on the profile where they all turn with a full-turn
    base, else in 3-D). With turn "auto" or "envelope", a full-turn arm with pairs the turn changes
    gets the enveloped model's margin on the profile, its `exact` pairs those of the upper bound,
    where every fixed body has an envelope (`kinematics.generic.turn_envelope`)."""
    from kinematics.generic.turn_envelope import turn_envelope

    reach = collision_reach(mech, robot, distances)
    native = mech.reach_search()
    if turn == "spatial" or (reach is native and native.setup.mode == "revolved"):  # (every pair turn-invariant)
        return SerialCollisionMargin(mech, robot, distances, reach), None
    why = (f"its reach search is {native.setup.mode} (no full base turn)" if native.setup.mode != "revolved" else
           "its base turns through part of a turn" if native.turn is not None else None)
    env = None if why else turn_envelope(model, _setup_configuration(robot, native), native.origin, native.basis[2],
                                         carried_joints(robot, native))
    if env is None:
        if turn == "envelope":  # asked for, and not possible: say so (the report's route says where it went)
            warnings.warn(KinematicsWarning(
                f"turn='envelope' does not apply to {mech.name}: "
                f"{why or 'a fixed body has no turn envelope (a half-space not normal to the base axis)'}; "
                f"measured {'in 3-D' if reach.setup.mode == 'spatial' else 'in its ' + reach.setup.mode + ' search'}"),
                stacklevel=2)
        return SerialCollisionMargin(mech, robot, distances, reach), None
    return SerialCollisionMargin(mech, robot, AnalyticDistances(env.model), native, exact=env.exact), env


def bracket(res: ColumnVolume, B: int, low: int, high: int, rtol: float) -> tuple[ColumnVolume, dict[str, Any]]:
    """A turn envelope's run (`Turn`) as the B branch targets of `res` and the union, the midpoint
    of the bracket of targets `low` (the lower bound) and `high` (the upper bound): its error the
    half-width plus the larger of the two error estimates (the true measure lies in
    [low - its error, high + its error]), converged where both bounds are and that error is
    <= rtol x the midpoint; the half-width is the error no finer step reduces (`fixed_error`).
    Also the report's entries of the two bounds."""
    keep = list(range(B))
    lo_v, hi_v = float(res.estimate[low]), float(res.estimate[high])
    half = 0.5 * max(hi_v - lo_v, 0.0)
    mid = 0.5 * (lo_v + hi_v)
    err = half + max(float(res.error[low]), float(res.error[high]))
    ok = bool(res.target_converged[low] and res.target_converged[high] and err <= rtol * abs(mid))
    out = dataclasses.replace(
        res, estimate=np.append(res.estimate[keep], mid), error=np.append(res.error[keep], err),
        check_difference=np.append(res.check_difference[keep], np.fmax(res.check_difference[low],
                                                                        res.check_difference[high])),
        target_converged=np.append(res.target_converged[keep], ok),
        check_agrees=np.append(res.check_agrees[keep], bool(res.check_agrees[low] and res.check_agrees[high])),
        fixed_error=np.append(np.zeros(len(keep)), half), converged=bool(res.converged and ok), rtol=rtol)
    bounds = {"route": "envelope", "lower": lo_v, "lower_error_estimate": float(res.error[low]),
              "upper": hi_v, "upper_error_estimate": float(res.error[high]), "half_width": half}
    return out, bounds


def bracket_estimate(margin: SerialCollisionMargin, cells: int) -> tuple[float, float]:
    """The width of a turn envelope's bracket and the upper bound's volume [m^3], estimated on a
    grid of `cells` points per axis over the profile (each point weighed 2 pi rho by its cell's
    area, Pappus): the points inside the upper bound but not the lower. A coarse guide (a thin
    bracketed region can fall between grid points) for choosing the route, not a result."""
    if margin.profile is None or margin.profile_margin is None or margin.exact is None:
        raise InvalidInputError("margin", "bracket_estimate needs a turn envelope's margin on a profile")
    lo, hi = margin.profile.lo, margin.profile.hi
    h = (hi - lo) / cells
    axes = [lo[k] + h[k] * (np.arange(cells) + 0.5) for k in range(2)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 2)
    cols = margin.profile_margin(pts)
    upper, lower = cols[:, -2] > 0, cols[:, -1] > 0
    weight = 2.0 * np.pi * np.abs(pts[:, 0]) * h[0] * h[1]
    return float(weight[upper & ~lower].sum()), float(weight[upper].sum())


class SerialCollisionMargin:
    """The collision-aware margin of a serial arm (module docstring) as a column engine margin:
    points (N, d) -> (N, 2 + W) columns: the kinematic margin k, the margin with each watched pair
    alone, then the union's m (`CollisionMargin`'s layout with no branch columns: an arm has none). On the profile (`on_profile`) its points are
    (rho, z); a revolved arm's 3-D margin carries that profile (`profile`) and answers 3-D points
    through it. A watched pair is a distance column (an int) or a group of them whose smallest is
    the pair's distance (a turn envelope's band pairs standing for one pair, `TurnEnvelope.original`)."""

    def __init__(self, mech: Mechanism, robot: Any, distances: AnalyticDistances, reach: Reach,
                 watched: Any = (), prescan: Prescan | None = None, on_profile: bool = False,
                 exact: np.ndarray | None = None) -> None:
        self.mech, self.robot, self.distances, self.reach = mech, robot, distances, reach
        # the pre-scan's one column of k: an arm has no branches, its margin is the union's
        self.branches, self.limits = (UNION,), "all"
        self.watched = tuple(np.atleast_1d(np.asarray(w, dtype=np.int64)) for w in watched)
        self.exact = None if exact is None else np.asarray(exact, dtype=np.int64)
        """With a turn envelope (`measure_collision_workspace`): the pairs of the upper bound, whose
        target (the union with these pairs alone) follows the watched pairs' columns."""
        self.prescan, self.on_profile = prescan, on_profile
        self.kinematic = ReachMargin(reach, on_profile)
        self.search_budget: int | None = SEARCHES if reach.setup.mode == "spatial" else None
        self.profile, self.profile_margin = None, None
        if reach.setup.mode == "revolved" and not on_profile:
            assert self.kinematic.profile is not None
            self.profile_margin = self.on_the_profile()
            self.profile = dataclasses.replace(self.kinematic.profile, margin=self.profile_margin)

    def on_the_profile(self) -> SerialCollisionMargin:
        """The same margin on the (rho, z) profile (revolved mode)."""
        return SerialCollisionMargin(self.mech, self.robot, self.distances, self.reach, self.watched, self.prescan,
                                     True, self.exact)

    def with_prescan(self, watched: Any, prescan: Prescan) -> SerialCollisionMargin:
        """This margin with `watched` pairs (columns or groups of them), the distances evaluated in
        `prescan`'s close cells only (a revolved arm's pre-scan is of its profile)."""
        return SerialCollisionMargin(self.mech, self.robot, self.distances, self.reach, watched, prescan,
                                     self.on_profile, self.exact)

    def for_check(self) -> SerialCollisionMargin:
        """The check run's margin: the search with twice the samples and restarts."""
        return SerialCollisionMargin(self.mech, self.robot, self.distances, self.reach.checker, self.watched,
                                     self.prescan, self.on_profile, self.exact)

    def _world(self, pts: np.ndarray) -> np.ndarray:
        return self.reach.profile_world(pts) if self.on_profile else self.reach.world(pts)

    def full_configurations(self, Q: np.ndarray) -> np.ndarray:
        """(N, nq) Pinocchio configurations of chain values Q (N, n): the joints off the chain or
        never searched at the setup's values."""
        values = np.tile(self.reach.setup.base, (len(Q), 1))
        values[:, self.reach.chain_dofs] = Q
        return configurations(self.robot, values)

    def evaluate(self, points: np.ndarray, signs: bool = True
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """At points (N, d): k (N,), the best configuration's smallest distance (N,) (+inf where
        not evaluated: k <= 0 or outside the pre-scan's close cells), each watched pair's best
        distance (N, W) (then, with `exact`, the best of the smallest over those pairs), every
        pair's distances at the best configuration (N, P) and its chain
        values (N, n) (the search's solution where not evaluated)."""
        pts = np.asarray(points, dtype=float)
        if self.profile_margin is not None:  # unchanged by the base's turn: the profile's
            return self.profile_margin.evaluate(self.reach.profile_of(pts), signs)
        world = self._world(pts)
        k, Q0 = (self.reach.profile_search(pts) if self.on_profile else self.reach.distance(world))
        P, W = len(self.distances.kinds), len(self.watched) + (self.exact is not None)
        best, watch, at = np.full(len(pts), np.inf), np.full((len(pts), W), np.inf), np.full((len(pts), P), np.inf)
        inside = k > 0
        if self.prescan is not None:
            inside &= self.prescan.close[0][self.prescan.cell_index(pts)]
        idx = np.flatnonzero(inside)
        if not len(idx) or not P:
            return k, best, watch, at, Q0
        D = self.distances.distances(self.full_configurations(Q0[idx]), signs=signs)
        best[idx], watch[idx], at[idx] = D.min(axis=1), self._grouped(D), D
        qbest = np.array(Q0)
        # colliding at the first solution: each restart's, then (still colliding) ESCALATE x as many
        n = self.reach.restarts
        for first, count in ((0, n), (n, (ESCALATE - 1) * n)):
            more = idx[best[idx] <= 0]
            if not len(more) or not count:
                break
            Qs, ok = self.reach.solutions(world[more], first, count)
            rows, cols = np.nonzero(ok)
            if not len(rows):
                continue
            Ds = np.full((len(more), Qs.shape[1], P), -np.inf)
            Ds[rows, cols] = self.distinct_distances(Qs[rows, cols], signs)
            low = Ds.min(axis=2)
            c = np.argmax(low, axis=1)
            better = low[np.arange(len(more)), c] > best[more]
            sel = more[better]
            best[sel] = low[better, c[better]]
            at[sel] = Ds[better, c[better]]
            qbest[sel] = Qs[better, c[better]]
            watch[more] = np.maximum(watch[more], self._grouped(Ds).max(axis=1))
        if self.reach.orientation is None and int(self.reach.searched.sum()) > len(self.reach.setup.rows):  # redundant
            self._escape(world, idx[best[idx] <= 0], qbest, best, watch, at, signs)
        return k, best, watch, at, qbest

    def distinct_distances(self, Q: np.ndarray, signs: bool = True) -> np.ndarray:
        """(K, P) every pair's signed distance [m] at chain values Q (K, n), each configuration
        evaluated once: rows that round to the same multiple of SAME_CONFIGURATION take the first
        one's distances."""
        _, first, inverse = np.unique(np.round(Q / SAME_CONFIGURATION), axis=0, return_index=True,
                                      return_inverse=True)
        return self.distances.distances(self.full_configurations(Q[first]), signs=signs)[np.ravel(inverse)]

    def _escape(self, world: np.ndarray, rows: np.ndarray, Q: np.ndarray, best: np.ndarray, watch: np.ndarray,
                at: np.ndarray, signs: bool) -> None:
        """Null-space steps of a redundant arm away from contact at the points `rows` (their best
        configurations Q still colliding), updating Q, best, watch and at in place where a step
        improves the smallest distance (module docstring)."""
        reach, dist = self.reach, self.distances
        moving = np.flatnonzero(reach.searched)
        for _ in range(ESCAPE_STEPS):
            if not len(rows):
                return
            q = Q[rows]
            pair = np.argmin(at[rows], axis=1)
            d0 = dist.pair_distances(self.full_configurations(q), pair)
            grad = np.zeros_like(q)
            for j in moving:  # the binding pair's gradient by forward differences
                qj = q.copy()
                qj[:, j] += ESCAPE_H
                grad[:, j] = (dist.pair_distances(self.full_configurations(qj), pair) - d0) / ESCAPE_H
            J = reach.jacobians(q)
            J[:, :, ~reach.searched] = 0.0
            step = grad - np.einsum("mij,mjk,mk->mi", np.linalg.pinv(J), J, grad)  # keeps the tool still
            norm = np.linalg.norm(step, axis=1)
            # a Newton step of the binding distance to ESCAPE_CLEARANCE along the projected gradient
            # (its directional derivative there is |step|), at most ESCAPE_ANGLE
            length = np.minimum((ESCAPE_CLEARANCE - d0) / np.maximum(norm, 1e-12), ESCAPE_ANGLE)
            seed = np.clip(q + step / np.maximum(norm, 1e-12)[:, None] * length[:, None], reach.lo, reach.hi)
            Qn, ok = reach.descend(world[rows], seed[:, None, :])
            D = np.full((len(rows), at.shape[1]), -np.inf)
            if ok[:, 0].any():
                D[ok[:, 0]] = dist.distances(self.full_configurations(Qn[ok[:, 0], 0]), signs=signs)
            low = D.min(axis=1)
            better = (low > best[rows]) & (norm > 1e-12)
            sel = rows[better]
            best[sel], at[sel], Q[sel] = low[better], D[better], Qn[better, 0]
            watch[sel] = np.maximum(watch[sel], self._grouped(D[better]))
            rows = sel[low[better] <= 0]

    def _grouped(self, D: np.ndarray) -> np.ndarray:
        """(..., W) each watched pair's distance of D (..., P) (the smallest over its group's
        columns), then, with `exact`, the smallest over those pairs (+inf: none)."""
        groups = [*self.watched, *(() if self.exact is None else (self.exact,))]
        out = np.full((*D.shape[:-1], len(groups)), np.inf)
        for n, cols in enumerate(groups):
            if len(cols):
                out[..., n] = D[..., cols].min(axis=-1)
        return out

    def branch_distances(self, points: np.ndarray, b: int, inside: np.ndarray, signs: bool = True) -> np.ndarray:
        """(M, P) pair distances at the best configuration found at the points `inside` (a mask)
        (the pre-scan's; +inf where the search reaches none)."""
        return self.evaluate(np.asarray(points, dtype=float)[inside], signs)[3]

    def __call__(self, points: np.ndarray) -> np.ndarray:
        k, best, watch, _, _ = self.evaluate(points)
        m = np.where(k > 0, np.minimum(k, best), k)
        w = np.where(k[:, None] > 0, np.minimum(k[:, None], watch), k[:, None])
        return np.column_stack([k, w, m])


VIEW_CELLS = 24
"""A collision view's default grid points per axis over a serial arm's task box in 3-D (on a
revolved arm's (rho, z) profile or a planar arm's plane, twice as many): the ur5's 13,824 grid
points, 3,184 of them reached, split in 1.4 s (each reached point a search and every pair's
signed distance at the configurations found; 2026-11-27, load 4 on 2 cores)."""


@dataclass(frozen=True, eq=False)
class CollisionGrid:
    """A serial arm's task-space grid split into collision-free and colliding points
    (`collision_grid`).

    Attributes:
        points: (N, d) the grid points the search reaches: task points (a planar arm's in its
            plane; a revolved arm's on its profile's half-plane at azimuth 0, in the world frame).
        free: (N,) a configuration found reaches the point with every checked pair apart.
        pair: (N,) where not free, the index (into the collision model's pairs) of the pair with
            the smallest signed distance at the best configuration found, < 0; -1 where free.
        q: (N, n) the chain values of the best configuration found (the free one where free).
        mode: "planar", "revolved" (the grid is the profile's: the set is a solid of revolution
            about `axis`) or "spatial".
        step: grid step [m]; grid_points: points searched (the whole grid, reached or not).
        axis: (origin, direction) of the base axis (revolved), else None.
        margin: the `SerialCollisionMargin` evaluated (its `full_configurations`, its search).
    """

    points: np.ndarray
    free: np.ndarray
    pair: np.ndarray
    q: np.ndarray
    mode: str
    step: float
    grid_points: int
    axis: tuple[np.ndarray, np.ndarray] | None
    margin: SerialCollisionMargin

    def counts(self) -> GridCounts:
        """The grid's counts: reached (free + colliding; a revolved grid's are profile points,
        each standing for its circle about the base axis), free, and the binding pairs by links
        with their point counts (`collisions.binding_pairs`)."""
        from kinematics.analyses.collisions import GridCounts, binding_pairs

        return GridCounts(self.mode, self.step, self.grid_points, len(self.points), int(self.free.sum()),
                          tuple(binding_pairs(self.margin.distances.model, self.pair, ~self.free)))

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready counts (`GridCounts.as_dict`)."""
        return self.counts().as_dict()


def collision_grid(mech: Mechanism, robot: Any, model: CollisionModel, step: float | None = None,
                   limit: int = MAX_COLLISION_VIEW_POINTS) -> CollisionGrid:
    """The cell centres of a grid of `step` [m] over a serial arm's task box that its search
    reaches, each split into collision-free or colliding with its binding pair (`CollisionGrid`),
    by the collision-aware margin (module docstring: the best of the configurations found). Where
    every pair turns with a full-turn base (`collision_reach`), the grid is the (rho, z) profile's
    (a point stands for its circle about the base axis), else the task box's (3-D, or a planar
    arm's plane). Default step: the box's longest side / VIEW_CELLS in 3-D, / (2 VIEW_CELLS) on a
    profile or plane. Raises `InvalidInputError` (naming --step) when the grid has more than
    `limit` points."""
    from kinematics.sizes import cell_centres, check_points, grid_points

    dist = AnalyticDistances(model)
    reach = collision_reach(mech, robot, dist)
    margin = SerialCollisionMargin(mech, robot, dist, reach)
    mode = reach.setup.mode
    lo, hi = (margin.profile.lo, margin.profile.hi) if margin.profile is not None else reach.box()
    if step is None:
        step = float(np.max(hi - lo)) / (VIEW_CELLS * (2 if len(lo) == 2 else 1))
    check_points("--step", grid_points(lo, hi, step), limit=limit,
                         hint=f"{step:g} m is too fine a step for a serial arm's collision view (each reached point "
                              "costs a search and every pair's distance)")
    pts = cell_centres(lo, hi, step)
    if margin.profile is not None:
        pts = reach.profile_world(pts)
    k, best, _, at, q = margin.evaluate(pts)
    reached = k > 0
    free = reached & (best > 0)
    pair = np.full(len(pts), -1, dtype=np.int64)
    hit = reached & ~free
    if hit.any():
        pair[hit] = np.argmin(at[hit], axis=1)
    axis = (reach.origin, reach.basis[2]) if margin.profile is not None else None
    return CollisionGrid(pts[reached], free[reached], pair[reached], q[reached], mode, float(step), len(pts), axis,
                         margin)


__all__ = ["VIEW_CELLS", "CollisionGrid", "SerialCollisionMargin", "Turn", "bracket", "bracket_estimate", "carried_joints",
           "collision_grid",
           "collision_reach", "serial_margin", "turn_invariant"]
