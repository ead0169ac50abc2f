"""The branches of a closed-loop mechanism (`LoopAtlas`): the *atlas* of branches (every label
with one configuration) is found once, at the end effector's reference position, from `seeds`
random starts within the joint limits (converged, deduplicated by the positions of every joint
origin, labelled), plus, for locked joints (`LoopStructure.locked_joints`), closed poses with
them half a turn away wherever the end effector then is (`_other_assemblies`); and `BranchSolutions`, the inverse kinematics of a batch of targets in every
branch of the atlas.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from kinematics.errors import UnsupportedRobotError
from kinematics.generic.loop_batch.compiled import REVOLUTE, TOL
from kinematics.generic.loop_batch.structure import LoopStructure


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


class LoopAtlas(LoopStructure):
    """The branch search at the reference position (a part of `LoopBatch`)."""

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
        if self.locked_joints:
            x, lab = self._other_assemblies(x, lab, seeds, rng)
        dist = self._distance_to_reference(x)
        best: dict[tuple[int, ...], int] = {}
        for i in np.argsort(dist):
            key = tuple(int(v) for v in lab[i])
            best.setdefault(key, int(i))
        keys = sorted(best, reverse=True)
        self.labels = tuple(keys)
        self.atlas = np.array([x[best[k]] for k in keys])

    def _other_assemblies(self, x: np.ndarray, lab: np.ndarray, seeds: int, rng: np.random.Generator
                          ) -> tuple[np.ndarray, np.ndarray]:
        """The atlas poses `x` (labels `lab`) found at the reference position, plus closed poses
        of the locked joints' other angles (half a turn from the reference's) whose labels are
        missing: an assembly in a parallel plane need not reach the reference position (the iso
        five-bar's second plane), so these are closed with the closure rows alone, the end
        effector free, from `seeds` random starts with the locked joints turned by pi; their
        atlas poses lie elsewhere in the task space (a cold start is one pose per label)."""
        L = len(self.label_blocks)
        locked = list(self.locked_joints)
        have = {tuple(int(v) for v in row[L:]) for row in lab}
        rows = np.zeros(self._m, dtype=np.bool_)
        rows[[i for g in self._row_groups()[: len(self._g[9])] for i in g]] = True
        extra_x, extra_lab = [x], [lab]
        for code in range(1, 2 ** len(locked)):
            bits = tuple(-1 if code >> q & 1 else 1 for q in range(len(locked)))
            if bits in have:
                continue
            x0 = self.seed_configurations(seeds, rng)
            x0[:, locked] = self._reference[locked] + np.pi * np.array([b < 0 for b in bits])
            t = np.repeat(self._anchor[None], seeds, axis=0)
            y, res, _ = self.newton(t, x0, iters=100, rows=rows)
            y = self.canonical(y[res <= TOL])
            if not len(y):
                continue
            _, J, _ = self.evaluate(t[: len(y)], y)
            got = self.label_of(J, y)
            keep = np.all(got != 0, axis=1) & np.all(got[:, L:] == np.array(bits), axis=1)
            extra_x.append(y[keep])
            extra_lab.append(got[keep])
        return np.vstack(extra_x), np.vstack(extra_lab)
