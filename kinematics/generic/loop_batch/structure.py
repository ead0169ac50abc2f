"""The structure of the loop equations (`LoopStructure`): the blocks they split into, the branch
labels, and the concurrent joint groups whose two representations are one pose.

**Branches (working modes).** With the end effector fixed the equations split into blocks
(`blocks`): groups of rows (a closure, the task) that determine a set of unknowns on their own,
found once from the Jacobian's sparsity (a greedy block-triangular ordering over single rows
groups, then pairs, then triples). A square block that contains an actuated joint decides that
actuator's working mode: the sign of its determinant cannot change without the block losing rank
(a type I singularity), so the vector of those signs labels a branch and is stable across each
singularity-free region of the workspace. Each block is also a small model of its own
(`block_models`), which the block solver (`blocks`) runs the compiled solver on.

A passive sub-chain can reach one position in several ways that are the same mechanism pose (a
universal joint's (a, b) and (a + pi, pi - b), a spherical joint's two Euler triples); they are
merged (same joint-origin positions) and the one closest to the reference configuration is kept,
so the labels and the reported joint values use one representation throughout.

**Locked joints (assembly modes in parallel planes).** In a planar closed motion of a spatial tree,
a revolute joint that no closed motion moves at the reference (`locked_joints`: its entry in every
null vector of the closure rows vanishes) is held by the loops at one angle up to the assembly: Gepetto's `5bar_linkage_iso3d` closes with its
extra joint `freeortho` at 0 or pi, its tip then in the plane y = -0.2 m or y = -0.15 m. The
determinant's sign does not tell these apart (both assemblies have both signs), so each locked
joint adds a label column, sign(cos(x_j - x_j_ref)): +1 at the reference's angle, -1 half a turn
from it, carried by the labelling block that determines the joint.
"""

from __future__ import annotations

import functools
import itertools
import math
from typing import Any, NamedTuple

import numpy as np

from kinematics.errors import UnsupportedRobotError
from kinematics.generic.loop_batch.compiled import REVOLUTE
from kinematics.generic.loop_batch.model import LoopModel, row_pattern, sparsity
from kinematics.generic.loop_batch.spheres import SphereCut, sphere_cuts, wrap


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
        locks: sub-model indices of the block's locked joints (`LoopStructure.locked_joints`)
            among its unknowns, whose label columns are among `LoopStructure.lock_columns[label]`.
        ends: the block's joints (degree-of-freedom indices) in the order the block solver keeps
            their values: its unknowns (`cols`), then each cut's triple.
        cuts: the block's 6D closures solved as point closures (`spheres.SphereCut`), their
            triples in closed form.
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
    locks: np.ndarray
    ends: tuple[int, ...]
    cuts: tuple[SphereCut, ...]


class LoopStructure(LoopModel):
    """Blocks, labels and joint groups of the loop equations (a part of `LoopBatch`)."""

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

    @functools.cached_property
    def locked_joints(self) -> tuple[int, ...]:
        """Revolute joints, not actuated, in a labelling block, that no closed motion moves at the
        reference configuration (module docstring): their entries in an orthonormal basis of the
        null space of the closure rows' Jacobian are below 1e-9 (the basis is computed to ~1e-12).
        Only for a planar closed motion of a spatial tree (`motion_plane(...).closed`): a spatial
        mechanism's passive joints can stand still at a symmetric reference (the 3-[P2(US)]'s,
        the Delta's) without being held at two angles."""
        from kinematics.generic.motion_plane import motion_plane

        plane = motion_plane(self.robot)
        if plane is None or not plane.closed:
            return ()
        groups = self._row_groups()
        rows = [i for g in groups[: len(self._g[9])] for i in g]
        _, J, _ = self.evaluate(np.repeat(self._anchor[None], 1, axis=0), self._reference[None])
        K = J[0, rows]
        _, s, Vt = np.linalg.svd(K)
        rank = int(np.sum(s > 1e-9 * s[0])) if s.size and s[0] > 0 else 0
        N = Vt[rank:]
        blocked = {c for b in self.label_blocks for c in b.cols}
        act = set(self.actuated.tolist())
        return tuple(j for j in range(self.n) if self._g[1][j] == REVOLUTE and j not in act and j in blocked
                     and float(np.abs(N[:, j]).max(initial=0.0)) <= 1e-9)

    @functools.cached_property
    def lock_columns(self) -> tuple[tuple[int, ...], ...]:
        """Per labelling block, the label columns of its locked joints (after the blocks' own
        columns, in `locked_joints` order)."""
        L = len(self.label_blocks)
        out: list[tuple[int, ...]] = []
        for b in self.label_blocks:
            out.append(tuple(L + q for q, j in enumerate(self.locked_joints) if j in b.cols))
        return tuple(out)

    @property
    def branch_names(self) -> tuple[str, ...]:
        """Readable branch labels: one +/- per labelling block, then per locked joint
        "/NAME=ANGLE", its angle [rad] at the branch's atlas pose to 3 decimals (e.g. "+/freeortho=-3.142")."""
        L = len(self.label_blocks)
        names = []
        for b, lab in enumerate(self.labels):
            text = "".join("+" if s > 0 else "-" for s in lab[:L])
            for j in self.locked_joints:
                text += f"/{self.robot.dofs[j].name}={round(float(self.atlas[b][j]), 3) + 0.0:g}"
            names.append(text)
        return tuple(names)

    def label_of(self, J: np.ndarray, x: np.ndarray) -> np.ndarray:
        """(R, L + locked) branch labels at solutions x with Jacobians J: per labelling block, the
        sign of its determinant times sign(cos b) of every concurrent group's middle angle b in the
        block (a group contributes exactly a factor cos b to the determinant: its joints' columns are
        a fixed map of their angular-velocity axes, whose determinant is +-cos b, so the product
        does not depend on the group's representation and keeps its sign through the group's own
        gimbal lock), 0 where the block is singular (type I); then per locked joint j,
        sign(cos(x_j - x_j_ref)) (+1 or -1: which of its two assembly angles)."""
        L = len(self.label_blocks)
        out = np.empty((len(J), L + len(self.locked_joints)), dtype=np.int8)
        for k, b in enumerate(self.label_blocks):
            sub = J[:, list(b.rows)][:, :, list(b.cols)]
            sign = np.sign(np.linalg.det(sub))
            for grp in self.concurrent_groups:
                if grp[1] in b.cols:
                    sign = sign * np.sign(np.cos(x[:, grp[1]]))
            out[:, k] = sign.astype(np.int8)
        for q, j in enumerate(self.locked_joints):
            out[:, L + q] = np.where(np.cos(x[:, j] - self._reference[j]) < 0.0, -1, 1)
        return out

    @functools.cached_property
    def sphere_cuts(self) -> dict[int, SphereCut]:
        """The 6D closures that end in a spherical triple (`spheres`), by closure index."""
        return sphere_cuts(self._g, self.concurrent_groups)

    @functools.cached_property
    def block_models(self) -> tuple[BlockModel, ...]:
        """Each block of `blocks` as a small model of its own (`BlockModel`), for the block solver;
        where `spheres`, a 6D closure of `sphere_cuts` whose triple the block determines (the
        platform not placed) as the point closure at the triple's centre, the triple solved after
        it in closed form."""
        return self.sub_models(self.spheres)

    def sub_models(self, cut: bool) -> tuple[BlockModel, ...]:
        """`block_models` with (cut) or without the cuts."""
        parent, kind, axis, jR, jt, fparent, _, _, _, ctype, cf1, cf2, ee, taxes, R0, orient, scale = self._g
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
            cuts = [self.sphere_cuts[c] for c in closures if cut and c in self.sphere_cuts and not pinned
                    and set(self.sphere_cuts[c].joints) <= set(blk.cols)]
            cut_of = {cut.closure: cut for cut in cuts}
            spec, frames = self._block_frames(closures, task or pinned, cuts)
            joints: set[int] = set()
            for f in frames:
                chain = set(self._chain(spec[f][0]))
                if pinned and carrier in chain:  # carried by the placed joint: the path below it only
                    chain = {j for j in chain if self._descends(j, carrier)}
                joints |= chain
            js = np.array(sorted(joints), dtype=np.int64)
            where = {int(j): i for i, j in enumerate(js)}
            sub_parent = np.array([-1 if (pinned and j == carrier) or parent[j] < 0 else where[int(parent[j])]
                                   for j in js], dtype=np.int64)
            sub_anc = np.zeros((len(frames), len(js)), dtype=np.bool_)
            for i, f in enumerate(frames):
                j = where[spec[f][0]]
                while j >= 0:
                    sub_anc[i, j] = True
                    j = int(sub_parent[j])
            fi = {f: i for i, f in enumerate(frames)}
            # an end effector the block does not use points at its first frame; its rows weigh 0
            sub_ee = fi.get(int(ee), 0)
            sub_fparent = np.array([where[spec[f][0]] for f in frames], dtype=np.int64)
            held_orient = bool(orient) and task
            sub_ctype = np.array([0 if c in cut_of else ctype[c] for c in closures], dtype=np.int64)
            ends1 = [("centre", c) if c in cut_of else int(cf1[c]) for c in closures]
            ends2 = [("other", c) if c in cut_of else int(cf2[c]) for c in closures]
            g = (sub_parent, kind[js], axis[js], jR[js], jt[js], sub_fparent,
                 np.array([spec[f][1] for f in frames]).reshape(-1, 3, 3), np.array([spec[f][2] for f in frames]).reshape(-1, 3),
                 sub_anc, sub_ctype, np.array([fi[f] for f in ends1], dtype=np.int64),
                 np.array([fi[f] for f in ends2], dtype=np.int64), int(sub_ee), taxes, R0, held_orient, float(scale))
            # full row -> sub-model row (a cut closure: its position rows only)
            to_sub: dict[int, int] = {}
            r = 0
            for c in closures:
                for i in groups[c][: 3 if c in cut_of else None]:
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
            sub_rows = [to_sub[i] for i in blk.rows if i in to_sub]
            weights = np.zeros(m)
            weights[sub_rows] = 1.0
            pattern = row_pattern(sub_anc, g[9], g[10], g[11], int(sub_ee), m - sum(3 if t == 0 else 6
                                                                                       for t in sub_ctype))
            pattern[weights == 0.0] = False
            nzc, nzn = sparsity(pattern)
            free = np.isin(js, blk.cols)
            # an ancestor the block's rows do not depend on (a revolute turning the end effector
            # about its own point, for a position task) is neither solved nor held: the kernel
            # leaves it at 0, which changes nothing the block measures
            held = np.array([i for i, j in enumerate(js) if not free[i] and not (pinned and j == carrier)
                             and (owner[j] >= 0 or self._pattern[list(blk.rows), j].any())], dtype=np.int64)
            own = tuple((int(owner[js[i]]), models[int(owner[js[i]])].ends.index(int(js[i]))) if owner[js[i]] >= 0
                        else (-1, -1) for i in held)
            if any(o < 0 for o, _ in own):
                raise UnsupportedRobotError(self.robot.name, f"block {k} of the loop equations uses a joint that no "
                                            "earlier block determines")
            depends: set[int] = set()
            for o, _ in own:
                depends |= set(models[o].depends)
                if models[o].label >= 0:
                    depends.add(models[o].label)
                    depends |= set(self.lock_columns[models[o].label])
            solved = [c for c in blk.cols if c in where]
            models.append(BlockModel(
                block=blk, joints=js, free=free, held=held, owner=own,
                rows=np.array(sub_rows, dtype=np.int64),
                cols=np.array([where[c] for c in solved], dtype=np.int64),
                middles=np.array([where[c] for c in solved if c in middle], dtype=np.int64),
                label=label_index.get(blk, -1), depends=tuple(sorted(depends)), pinned=pinned, g=g, m=m,
                nzc=nzc, nzn=nzn, centre=self._centre[js], weights=weights,
                locks=np.array([where[j] for j in self.locked_joints if j in solved], dtype=np.int64),
                ends=tuple(solved) + tuple(j for cut in cuts for j in cut.joints), cuts=tuple(cuts)))
            owner[list(blk.cols)] = k
        return tuple(models)

    def _block_frames(self, closures: list[int], with_ee: bool, cuts: list[SphereCut]
                      ) -> tuple[dict[Any, tuple[int, np.ndarray, np.ndarray]], list[Any]]:
        """A block sub-model's frames, each (parent joint, R, t): the model's own (by index: the
        closures' that are not cut, the end effector's if with_ee, sorted), then each cut's two (by
        key ("centre", closure) and ("other", closure)); and their order."""
        fparent, fR, ft, cf1, cf2, ee = (self._g[i] for i in (5, 6, 7, 10, 11, 12))
        cut = {c.closure for c in cuts}
        spec: dict[Any, tuple[int, np.ndarray, np.ndarray]] = {}
        for c in closures:
            if c not in cut:
                for f in (int(cf1[c]), int(cf2[c])):
                    spec[f] = (int(fparent[f]), fR[f], ft[f])
        if with_ee:
            spec[int(ee)] = (int(fparent[ee]), fR[ee], ft[ee])
        frames: list[Any] = sorted(spec)
        for sc in cuts:
            spec[("centre", sc.closure)], spec[("other", sc.closure)] = sc.centre, sc.other
            frames += [("centre", sc.closure), ("other", sc.closure)]
        return spec, frames

    def _chain(self, j: int) -> list[int]:
        """Joint j and its ancestors (none for the base, -1)."""
        out = []
        while j >= 0:
            out.append(j)
            j = int(self._g[0][j])
        return out

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
        x[..., revolute] = wrap(x[..., revolute], self._centre[revolute])
        return x

    def _descends(self, j: int, ancestor: int) -> bool:
        parent = self._g[0]
        while j >= 0:
            if j == ancestor:
                return True
            j = int(parent[j])
        return False
