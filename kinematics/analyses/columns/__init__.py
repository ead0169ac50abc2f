"""Volume (or area) of {x : f(x) >= 0} by column integration: exact columns, adaptive quadrature.

The region is given by a continuous *margin* f (positive inside, in metres) over a box that
contains it. One axis (the shortest side by default) is the *column axis*; a column's inside
length l is integrated over the other axes. Two paths:

**Exact columns** (3D margins with an `exact_columns` attribute, such as the 3-[P2(US)]'s, see
`kinematics.mechanisms.p2us.exact`): every column's intervals come exactly from roots of quadratics, with a
*signature* that changes wherever l is not smooth (another constraint takes over an end, an
interval appears or vanishes, a face parallel to the axis). Slice areas A(x) = integral of
l(x, y) dy by `piecewise_1d`: nodes every `step` (at least MIN_NODES), breaks located by
bisection on the signature, each smooth piece integrated by adaptive Gauss-Legendre rules after
the grading y = u + (v - u)(3t^2 - 2t^3), which makes square-root edges analytic. The volume
V = integral of A(x) dx by `adaptive_1d`. Nothing along a column can be missed; a feature
narrower than the node spacing in both quadrature directions can.

**Sampled columns** (any other margin): the margin every `step` along the column, every sign
change bracketed and refined (Illinois false position with a bisection safeguard and Brent's
tolerance nudge; bisection from a bracket's second stall on, where the margin jumps, as a
closed loop's does at the reach boundary) to a bracket narrower than `root_tol` (default
`ROOT_TOL` = 1e-12 m; the brackets' widths are part of the error estimate); nested `adaptive_1d`.

`adaptive_1d`: a Gauss-Legendre rule on every interval and on its two halves, the halves' sum
as its value and |whole - halves| as its error estimate, plus the variation bound
width x (max - min of the values) wherever the signature changes among its nodes (there l has
kinks, jumps or square-root edges, where the two rules can agree by accident). On smooth pieces
the difference is dominated by the whole interval's error, so the sum over the accepted
intervals is a conservative estimate; it is not a rigorous bound. Intervals are halved largest
estimate first until the sum meets rtol; the slices' own estimates (<= rtol / 4) are carried
into the outer integral.

**What the method can miss** (stated, not estimated):

* sampled columns only: along a column, an inside interval or an outside gap shorter than
  `step` can fall between two samples (the 3-[P2(US)] margin has no Lipschitz bound to skip
  ahead safely: its stroke and joint-angle terms go through sqrt(discriminant)). Near a surface
  grazing the columns this biases the volume low: 1.6e-4 relative on the 3-[P2(US)] at 5 mm;
* across columns, a feature between the nodes of every interval at every level is not seen.
  `check` reruns the whole computation at half the step (twice the nodes); where the two disagree
  beyond their error estimates, or the last target's difference exceeds its tolerance, it halves
  the step again, up to CHECK_HALVINGS times in all, and compares the last two runs (a sliver thinner than the step shrinks with it: between two
  boundaries tangent to each other, the part a column can miss has an area of order step^1.5).
  The result is the finest run's, its error at least the last two runs' difference; it reports
  not converged if even those disagree.
"""

from .engine import (
    CHECK_HALVINGS,
    MIN_NODES,
    OUTER_SPAN,
    RTOL_FLOOR,
    ColumnVolume,
    ExactColumnsFn,
    column_volume,
)
from .quadrature import BREAK_WIDTH, adaptive_1d, piecewise_1d
from .sampled import CHUNK_POINTS, ROOT_TOL, Counter, column_lengths

__all__ = [
    "BREAK_WIDTH", "CHECK_HALVINGS", "CHUNK_POINTS", "MIN_NODES", "OUTER_SPAN", "ROOT_TOL", "RTOL_FLOOR",
    "ColumnVolume", "Counter", "ExactColumnsFn", "adaptive_1d", "column_lengths", "column_volume", "piecewise_1d",
]
