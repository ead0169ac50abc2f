"""Reachable workspace of a frame's position for any serial arm, with guaranteed bounds.

W = f(Q), f the frame position and Q the box of joint limits. The method (derivation in
docs/serial-workspace.md) partitions Q into boxes, evaluates f and its Jacobian J at each box's
centre s with the compiled batched kinematics, and keeps two sets of task-space cells of side h:

* **inside** (a lower bound): (1) Graves' surjection theorem. With sigma = sigma_min(J(s))
  (position rows), M a bound on the second derivative of f over Q (`SerialWorkspace.hessian_bound`)
  and the joint ball B(s, r) inside the limits, f(B(s, r)) contains the task ball
  B(f(s), (sigma - M r) r); r = min(sigma / 2M, distance to the limits). Cells lying wholly in such
  a ball are in W. (2) dW lies in f(limit faces) u f(rank-deficient configurations): the cells met
  by the balls of boxes that may hold such points cover it, and each face-connected component of
  the other cells is wholly in W (if it holds a reached point or a Graves cell) or wholly out.
* **touched** (an upper bound): Taylor, B_ij bounding |d^2 f / dq_i dq_j|. For q in a box of
  half-widths d, |f(q) - f(s)| <= eps = sum_i |J_i(s)| d_i + sum_ij B_ij d_i d_j / 2, so the box's
  image lies in B(f(s), eps). A box whose ball lies inside the certified cells is settled; the
  others are split (along the joints that dominate eps) until eps <= h / 2, and the cells their
  balls meet are marked.

W lies between the two cell sets whatever the sampling: lower <= |W| <= upper, up to rounding
(~1e-15 relative). The estimate is their midpoint, the error estimate their half-gap. Reductions
(exact): joints that never move the point are fixed; when the first joint of the chain is a
revolution about a fixed axis with a full turn of range, W is a solid of revolution and the
measure is 2 pi int rho d(rho) dz over the reachable (rho, z) profile (Pappus); a planar arm's
measure is the area in its plane.

Dexterity (Yoshikawa index, condition number, smallest radius of the position Jacobian's
ellipsoid) is aggregated per cell as the best over the evaluated configurations reaching it.
Boxes with sigma_min(J(s)) <= sum_i d_i |dJ/dq_i| may contain a configuration where J loses rank
(sigma_min is 1-Lipschitz in the matrix); the others are singular-free. The singular set's image lies within the
reported balls.

Modules: `measure` (`serial_workspace`, the driver), `joint_box` (the joints sampled, the mode,
the derivative bounds), `boxes` (level 0, evaluation at the boxes' centres, splitting), `kernels`
(compiled cell marking, the Jacobian's singular values, `radii`), `result` (`SerialWorkspace`,
`CellGrid`).
"""

from __future__ import annotations

from kinematics.analyses.serial_workspace.kernels import radii as radii
from kinematics.analyses.serial_workspace.measure import serial_workspace as serial_workspace
from kinematics.analyses.serial_workspace.result import CellGrid as CellGrid
from kinematics.analyses.serial_workspace.result import SerialWorkspace as SerialWorkspace

