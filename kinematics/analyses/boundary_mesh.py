"""Workspace boundaries as watertight triangle meshes (STL, PLY, glTF binary).

A mechanism's margin field (>= 0 inside, `Mechanism.margin`) is sampled on a grid of step h
over the workspace's bounding box padded by two steps, whose outer layer is forced negative so the
iso-surface closes; scikit-image's marching cubes extracts the zero level set and trimesh checks
that it is watertight and measures its enclosed volume.

Tolerance against the volume engine. Marching cubes interpolates the zero crossing on every grid
edge, so a cell whose 8 corners share a sign is taken as wholly inside or outside, and the mesh
only differs from the true region inside the cells whose corners change sign (assuming no feature
thinner than a cell). Hence |V_mesh - V| <= N_b h^3, N_b the number of such boundary cells
(`BoundaryMesh.tolerance`): about the surface area times h, the bound the issue asks for, but
counted exactly on the grid.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from kinematics.errors import InvalidInputError
from kinematics.mechanisms.base import Mechanism, check_mechanism
from kinematics.sizes import check_points, grid_points

MESH_SUFFIXES = (".stl", ".ply", ".glb")


@dataclass(frozen=True)
class BoundaryMesh:
    """A closed boundary mesh.

    Attributes:
        mesh: the trimesh.Trimesh (outward normals).
        step: grid step [m]. boundary_cells: cells whose corners change sign.
    """

    mesh: Any
    step: float
    boundary_cells: int

    @property
    def volume(self) -> float:
        """Enclosed volume [m^3]."""
        return float(self.mesh.volume)

    @property
    def tolerance(self) -> float:
        """Bound on |volume - true volume| [m^3]: boundary_cells x step^3 (module doc)."""
        return self.boundary_cells * self.step**3

    @property
    def watertight(self) -> bool:
        return bool(self.mesh.is_watertight)


def margin_mesh(margin: Callable[[np.ndarray], np.ndarray], lo: ArrayLike, hi: ArrayLike,
                step: float) -> BoundaryMesh:
    """Zero level set of a scalar field (N, 3) -> (N,) over the box `[lo, hi]` [m] at grid `step`."""
    import trimesh
    from skimage.measure import marching_cubes

    if not (step > 0 and math.isfinite(step)):
        raise InvalidInputError("step", f"must be a positive number of metres, got {step!r}")
    lo_ = np.asarray(lo, float) - 2 * step
    hi_ = np.asarray(hi, float) + 2 * step
    check_points("step", grid_points(lo_.tolist(), hi_.tolist(), step), hint="use a larger step")
    axes = [lo_[k] + step * np.arange(math.ceil((hi_[k] - lo_[k]) / step) + 1) for k in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1)
    v = np.asarray(margin(grid.reshape(-1, 3)), float).reshape(grid.shape[:-1])
    # the region lies inside [lo, hi]: forcing the padded shell negative closes the surface
    for ax in range(3):
        for end in (0, -1):
            sl: list[Any] = [slice(None)] * 3
            sl[ax] = end
            v[tuple(sl)] = np.minimum(v[tuple(sl)], -step)
    # a value exactly on the level gives zero-area triangles that break the mesh's manifoldness:
    # count such grid points as outside (the region is closed, so this moves the surface by < 1e-9 h)
    v[v == 0.0] = -1e-9 * step
    if not (v >= 0).any():
        raise InvalidInputError("mode", "the workspace is empty at this grid step (no grid point inside)")
    verts, faces, _, _ = marching_cubes(v, level=0.0, spacing=(step, step, step))
    # marching cubes already shares vertices; merging near-coincident ones could pinch the surface
    mesh = trimesh.Trimesh(verts + lo_, faces, process=False)
    if mesh.volume < 0:
        mesh.invert()
    inside = v >= 0
    corners = [inside[i:inside.shape[0] - 1 + i, j:inside.shape[1] - 1 + j, k:inside.shape[2] - 1 + k]
               for i in (0, 1) for j in (0, 1) for k in (0, 1)]
    n_in = np.sum(corners, axis=0)
    boundary = int(np.count_nonzero((n_in > 0) & (n_in < 8)))
    return BoundaryMesh(mesh, step, boundary)


def workspace_mesh(mech: Mechanism, branch: str | None = None, step: float = 0.01, limits: str = "all"
                   ) -> BoundaryMesh:
    """The boundary of a branch's workspace ("union": of every branch; None: "---" where the
    mechanism has it, else its first branch, or the union of a serial arm) of a 3-D mechanism
    with a margin (`Mechanism.margin`), over its bounding box at grid step `step` [m]."""
    check_mechanism(mech, "workspace_mesh")
    mech.require("margin", "a workspace boundary mesh")
    if mech.task_dim != 3:
        from kinematics.errors import UnsupportedRobotError

        raise UnsupportedRobotError(mech.name, "a boundary mesh needs a spatial task space; this mechanism's is "
                                    f"{mech.task_dim}-dimensional")
    if branch is None:
        from kinematics.analyses.usable import default_branch

        branch = default_branch(mech)
    chosen = mech.check_target(branch)
    field = mech.margin(chosen, limits)
    lo, hi = mech.bounding_box(limits)
    return margin_mesh(lambda p: field(p)[:, -1], lo, hi, step)


def export(mesh: BoundaryMesh, path: str) -> None:
    """Write the mesh by suffix (.stl, .ply, .glb) to exactly `path` (callers make it atomic)."""
    import os

    ext = os.path.splitext(path)[1].lower()
    if ext not in MESH_SUFFIXES:
        raise InvalidInputError("-o", f"{path!r}: unknown suffix {ext or '(none)'!r}; use one of "
                                      f"{', '.join(MESH_SUFFIXES)}")
    data = mesh.mesh.export(file_type=ext[1:])
    with open(path, "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())
