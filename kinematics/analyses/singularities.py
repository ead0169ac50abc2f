"""Singularity scans: type I / II / III loci of any mechanism with singular fields (the
3-[P2(US)], the Delta) over a Cartesian grid. (Paper B's own 512-point actuator scan is
`kinematics.mechanisms.p2us.paper_scan`; the SCARA's theta2 = 0 boundary with its smallest-radius
map is `kinematics.mechanisms.scara.closed_form.singular_set`.)

Loci are found where a mechanism's signed fields (`Mechanism.singular_fields`) change sign
between grid neighbours (and placed by linear interpolation along that edge), which catches a
singular surface whatever the grid step, where a threshold on |measure| would catch only the
points that happen to land on it:

* type I (limb i): the IK discriminant of limb i changes sign: the limb's two roots merge (for
  the 3-[P2(US)] its rod is perpendicular to its rail; for the Delta its forearm lies in the
  plane of its upper arm and actuator axis: J_q singular). Such points lie on the limb's reach boundary,
  so at best on the workspace's boundary, never in its interior; one counts as *on the
  workspace boundary* when its reachable end is in some working mode's workspace.
* type II (mode m): det[n_1; n_2; n_3] of the rod (forearm) directions changes sign with every
  limb reaching at both ends (J_x singular); *in the workspace* when both ends are in mode m's workspace.
* type III: a type II edge that shares an end with a type I edge (both within one step).

The grid is scanned plane by plane along z, so memory stays at a few planes whatever the step; a
planar task space (x, y) is a single plane, and its loci are curves.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinematics.analyses.cells import check_step
from kinematics.analyses.singular_edges import edge_crossings
from kinematics.mechanisms.base import Mechanism, check_mechanism
from kinematics.mechanisms.three_limb.closed_form import MODES
from kinematics.sizes import check_points, grid_points


@dataclass(frozen=True)
class SingularLocus:
    """Points [m] on a singular locus and what they are.

    Attributes:
        points: (K, d) interpolated positions (d = the task dimension, 2 or 3).
        kind: (K,) 1 (type I), 2 (type II) or 3 (type III).
        which: (K,) the limb (type I, 0-based) or mode index into MODES (types II, III).
        inside: (K,) type II/III: in the (joint-limited) workspace; type I: on its boundary (see
            the module docstring).
    """

    points: np.ndarray
    kind: np.ndarray
    which: np.ndarray
    inside: np.ndarray
    branches: tuple[str, ...] = MODES

    @property
    def interior(self) -> np.ndarray:
        """(K,) type II/III points inside the workspace (type I never is)."""
        return self.inside & (self.kind != 1)

    def count(self, kind: int, inside_only: bool = False) -> int:
        sel = self.kind == kind
        if inside_only:
            sel &= self.inside
        return int(sel.sum())

    def as_list(self, interior_only: bool = True) -> list[dict[str, Any]]:
        """JSON-ready points: position, type, limb or mode, inside."""
        out = []
        keep = self.interior if interior_only else np.ones(len(self.kind), dtype=bool)
        for p, k, w, ins in zip(self.points[keep], self.kind[keep], self.which[keep], self.interior[keep], strict=True):
            item: dict[str, Any] = {"position": p.tolist(), "type": "I" * int(k) if k < 3 else "III",
                                    "inside_workspace": bool(ins)}
            if k == 1:
                item["limb"] = int(w) + 1
            else:
                item["mode"] = self.branches[int(w)]
            out.append(item)
        return out


@dataclass(frozen=True)
class SingularityScan:
    """Result of `singular_loci`."""

    locus: SingularLocus
    step: float
    limits: str
    modes: tuple[str, ...]
    points_evaluated: int
    seconds: float
    box: tuple[list[float], list[float]]
    extra: dict[str, Any] = field(default_factory=dict)

    def summary(self) -> dict[str, Any]:
        """Counts per type: all locus points, and those inside (type I: on the boundary of) the workspace."""
        return {
            "type_I": {"locus_points": self.locus.count(1), "on_workspace_boundary": self.locus.count(1, True)},
            "type_II": {"locus_points": self.locus.count(2), "inside_workspace": self.locus.count(2, True)},
            "type_III": {"locus_points": self.locus.count(3), "inside_workspace": self.locus.count(3, True)},
        }

    @property
    def any_inside(self) -> bool:
        """Some type II/III point lies inside the workspace (paper B says none does)."""
        return bool(self.locus.interior.any())


PLANES_POINTS = 1 << 18
"""Grid points per `singular_fields` call (whole planes) for closed-form mechanisms."""


def _crossings(fields: dict[str, np.ndarray], pts: np.ndarray, ids: np.ndarray, mode_cols: list[int], planes: int,
               dims: np.ndarray, out: list[tuple], z_only: bool = False) -> None:
    """The block's crossings (`singular_edges.edge_crossings`) placed on their edges, into out."""
    kind, which, t, a, b, inner = edge_crossings(fields["disc"], fields["det"], fields["margin"], mode_cols, planes,
                                                 int(dims[0]), int(dims[1]), z_only=z_only)
    out.append((kind, which, pts[a] + t[:, None] * (pts[b] - pts[a]), inner, ids[a], ids[b]))


def singular_loci(mech: Mechanism, *, step: float = 0.01, limits: str = "all",
                  branches: Sequence[str] | None = None, progress: bool = False) -> SingularityScan:
    """Type I / II / III loci of any mechanism with `singular_fields` over a grid of step `step`
    [m] on its bounding box (see the module docstring; for the 3-[P2(US)] the fields come from
    the fused scan kernel)."""
    check_mechanism(mech, "singular_loci")
    mech.require("singular_fields", "a singular-locus scan")
    if mech.task_dim not in (2, 3):
        from kinematics.errors import UnsupportedRobotError

        raise UnsupportedRobotError(mech.name, f"singular loci are scanned over a 2D or 3D grid; this task space "
                                               f"is {mech.task_dim}-dimensional ({', '.join(mech.task_axes)})")
    mech.check_limits(limits)
    check_step(step)
    chosen = mech.check_branches(branches)
    mode_cols = [mech.branches.index(m) for m in chosen]
    lo, hi = mech.bounding_box(limits)
    check_points("step", grid_points(lo, hi, step), hint=f"{step:g} m is too fine a step")
    dims = np.ceil((hi - lo) / step).astype(int) + 1
    planes = int(dims[2]) if len(dims) == 3 else 1  # a planar task space is one plane
    t0 = time.perf_counter()
    ix, iy = (a.ravel() for a in np.meshgrid(np.arange(dims[0]), np.arange(dims[1]), indexing="ij"))
    P = len(ix)  # points per plane; a point's id is plane x P + its index in the plane
    found: list[tuple] = []
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=planes, desc="singularities", unit="plane", delay=1.0, leave=False)
    prev = None
    # closed forms (a design in `params`): a point's fields do not depend on the batch, so several
    # planes go to one call (each call of a parallel kernel pays its threads' start-up) and their
    # edges are examined together; the generic solver, whose warm starts do depend on it, keeps one
    # plane per call
    per_call = max(1, PLANES_POINTS // P) if mech.params is not None else 1
    for k0 in range(0, planes, per_call):
        K = min(planes, k0 + per_call) - k0
        ks = np.arange(k0, k0 + K)
        zs = [np.repeat(lo[2] + step * ks, P)] if len(dims) == 3 else []
        pts = np.stack([np.tile(lo[0] + step * ix, K), np.tile(lo[1] + step * iy, K)] + zs, axis=1)
        fields = mech.singular_fields(pts, limits)
        cur = {"disc": fields.limb, "det": fields.det, "margin": fields.margin}
        ids = k0 * P + np.arange(K * P)
        _crossings(cur, pts, ids, mode_cols, K, dims, found)
        if prev is not None:  # the previous call's last plane to this call's first
            _crossings({n: np.concatenate([v, cur[n][:P]]) for n, v in prev[0].items()},
                       np.concatenate([prev[1], pts[:P]]), np.concatenate([prev[2], ids[:P]]), mode_cols, 2, dims,
                       found, z_only=True)
        last = slice((K - 1) * P, K * P)
        prev = ({n: v[last] for n, v in cur.items()}, pts[last], ids[last])
        if bar is not None:
            bar.update(K)
    if bar is not None:
        bar.close()
    locus = _assemble(found, mech.branches, int(np.prod(dims)))
    return SingularityScan(locus, step, limits, chosen, int(np.prod(dims)), time.perf_counter() - t0,
                           (lo.tolist(), hi.tolist()))


def _assemble(found: list[tuple], branches: tuple[str, ...], grid_size: int) -> SingularLocus:
    if not found:
        e = np.empty(0)
        return SingularLocus(np.empty((0, 3)), e.astype(int), e.astype(int), e.astype(bool), branches)
    kind = np.concatenate([f[0] for f in found])
    which = np.concatenate([f[1] for f in found])
    points = np.concatenate([f[2] for f in found])
    inside = np.concatenate([f[3] for f in found])
    ends_a = np.concatenate([f[4] for f in found])
    ends_b = np.concatenate([f[5] for f in found])
    type1 = np.zeros(grid_size, dtype=bool)  # the grid points at an end of a type I edge
    type1[ends_a[kind == 1]] = True
    type1[ends_b[kind == 1]] = True
    near = type1[ends_a] | type1[ends_b]
    kind = np.where((kind == 2) & near, 3, kind)
    return SingularLocus(points, kind, which, inside, branches)
