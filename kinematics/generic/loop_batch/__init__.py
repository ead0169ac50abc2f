"""A batched closed-loop solver for any URDF tree + loop sidecar: every working mode of many
task-space targets at once, their joint-limit margins and their singularity measures.

    from kinematics.generic.loop_batch import loop_batch

    batch = loop_batch(robot)                 # LoopBatch.from_robot(robot), cached per robot
    sol = batch.ik(points)                    # (N, d) task points: every branch (BranchSolutions)
    margins = batch.margin(points)            # (N, B + 1) joint-limit margins [m], then their union
    sing = batch.singularities(points, sol.x) # Gosselin-Angeles measures and types

The unknowns are all joint values (actuated and passive); the equations are the sidecar's closures
and the task (the end effector's position along the task axes and, for a translational mechanism,
its reference orientation), every row in metres, solved by Levenberg-Marquardt in compiled kernels.
With the end effector fixed the equations split into blocks; the sign of the determinant of each
square block that holds an actuated joint labels a working mode (a branch), and the atlas of
branches is found once, at the reference position. `ik` solves block by block (the default) or
every unknown of a branch at once (`solver="whole"`, the reference path), from solved neighbours,
the atlas configurations and quasi-random restarts. The block solver's restarts at a target are a
function of the target (not of its row in the batch), and a slot whose start closed on its
block's other root is restarted longer; the neighbours' starts still depend on the batch and on
earlier calls, and a branch that exists at a target can still be missed (`solver` says what is
and is not guaranteed).

One concept per module:

* `solver`: `LoopBatch` (`from_robot`: the task; `ik`, `margin`, `bounding_box`), `loop_batch`;
* `model`: the compiled model under it: tree and closure arrays, residual rows and their sparsity,
  `newton` and `evaluate`;
* `compiled`: the compiled kernels: the equations, Levenberg-Marquardt, one block at every target;
* `structure`: blocks, branch labels, concurrent joint groups (one representation per pose);
* `atlas`: the branches found at the reference position, `BranchSolutions`;
* `blocks`, `whole`: the block solver and the whole-system solver;
* `warm`: the warm-start cache of solved points;
* `spheres`: spherical joints behind 6D closures in closed form;
* `margins`: joint-limit margins;
* `singular`: velocities and singularity measures (`Singularities`).
"""

from __future__ import annotations

from typing import Any

from kinematics.generic.loop_batch.atlas import BranchSolutions as BranchSolutions
from kinematics.generic.loop_batch.compiled import TOL as TOL
from kinematics.generic.loop_batch.compiled import block_kernel, eval_kernel, lm_kernel
from kinematics.generic.loop_batch.margins import assemble_kernel, slack_kernel
from kinematics.generic.loop_batch.singular import Singularities as Singularities
from kinematics.generic.loop_batch.solver import SOLVERS as SOLVERS
from kinematics.generic.loop_batch.solver import LoopBatch as LoopBatch
from kinematics.generic.loop_batch.solver import loop_batch as loop_batch
from kinematics.generic.loop_batch.spheres import angles_kernel
from kinematics.generic.singularity import SINGULAR_TOL as SINGULAR_TOL


def kernels() -> tuple[Any, ...]:
    """The compiled kernels of this package (for `kinematics.jit`)."""
    return (lm_kernel, eval_kernel, block_kernel, assemble_kernel, slack_kernel, angles_kernel)
