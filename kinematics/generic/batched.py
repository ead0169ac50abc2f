"""Compiled batched kinematics for any serial Pinocchio model: frame poses and frame Jacobians
for arrays of configurations, on every core.

`BatchedKinematics` is built once per (model, frame) from what Pinocchio knows about the model:
the chain of joints from the world to the frame's parent joint, each joint's placement in its
parent (`model.jointPlacements`), its type, its axis (read from Pinocchio's motion subspace) and
the frame's placement in its parent joint. A Numba kernel then composes, per configuration,

    oMf = M_1 X_1(q) M_2 X_2(q) ... M_n X_n(q) jMf,

M_k the placement of joint k, X_k(q) its motion: a rotation by angle t about the unit axis a,

    R(t) = cos t I + sin t [a]x + (1 - cos t) a a^T        (Rodrigues, as Pinocchio),

(a column rotation when a is a coordinate axis), or a translation t a [m]. Continuous joints take
(cos t, sin t) straight from Pinocchio's configuration vector (nq = 2, nv = 1), like Pinocchio.
Fixed joints need nothing: Pinocchio merges them into the frame placements.

Frame Jacobians follow Pinocchio's LOCAL_WORLD_ALIGNED convention (as `kinematics.generic.serial`):
[v; w] = J q_dot with v the frame origin's velocity [m/s] and w the angular velocity [rad/s], both
in world axes. The column of joint k (world axis w_k = oR_k a_k, joint origin p_k) is

    revolute / continuous:  [w_k x (p_f - p_k); w_k],       prismatic:  [w_k; 0];

columns of joints that do not move the frame are zero.

Supported joints: revolute and prismatic about/along any axis (Pinocchio's RX/RY/RZ,
RevoluteUnaligned, PX/PY/PZ, PrismaticUnaligned), continuous (RUBX/RUBY/RUBZ,
RevoluteUnboundedUnaligned) and fixed joints; anything else (free-flyer, spherical, planar,
helical...) raises `UnsupportedRobotError`.

One kernel carries blocks of 256 configurations through the chain one joint at a time (each
step a loop over configurations, which vectorises), `prange` over the blocks, each with a small
scratch, so the extra memory is bounded whatever N; fastmath is off: results agree with
Pinocchio to ~1e-15. Sine and cosine are computed in the kernels (see `_sincos_reduced`).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from decimal import Decimal
from fractions import Fraction
from typing import NamedTuple

import numpy as np
import pinocchio as pin
from numba import njit, prange

from kinematics.errors import InvalidInputError, UnsupportedRobotError
from kinematics.model.robot import Robot

_NO_JACOBIAN = np.empty((0, 6, 0))

REVOLUTE, CONTINUOUS, PRISMATIC = 0, 1, 2

_KINDS = {
    **dict.fromkeys(("JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned"), REVOLUTE),
    **dict.fromkeys(
        ("JointModelRUBX", "JointModelRUBY", "JointModelRUBZ", "JointModelRevoluteUnboundedUnaligned"), CONTINUOUS
    ),
    **dict.fromkeys(("JointModelPX", "JointModelPY", "JointModelPZ", "JointModelPrismaticUnaligned"), PRISMATIC),
}
SUPPORTED = "revolute (any axis), continuous (any axis), prismatic (any axis) and fixed joints"
"""What `BatchedKinematics` accepts, as said in its error messages."""


class BatchedPoses(NamedTuple):
    """Frame placements in the world: positions [m] (N, 3) and rotation matrices (N, 3, 3).

    Both are views into one (N, 12) array `rows` (x y z, then the rotation row-major)."""

    position: np.ndarray
    rotation: np.ndarray
    rows: np.ndarray


@dataclass(frozen=True, eq=False)
class BatchedKinematics:
    """The compiled description of one frame of one model (build with `from_robot`/`from_model`).

    Attributes:
        name: the robot's name (for error messages).
        frame: the frame's name.
        nq, nv: Pinocchio's configuration and velocity dimensions of the whole model.
        kind: (n,) REVOLUTE / CONTINUOUS / PRISMATIC for each joint of the chain, root first.
        axis_index: (n,) 0/1/2 when the axis is +-e_x/e_y/e_z (a cheaper column rotation), else -1.
        axis: (n, 3) unit axis in the joint frame.
        idx_q, idx_v: (n,) first index of each chain joint in q and in v.
        rotation, translation: (n, 3, 3), (n, 3) joint placements in their parent joint.
        frame_rotation, frame_translation: (3, 3), (3,) frame placement in the last chain joint.
        continuous_q: (m,) index in q of the cosine of every continuous joint of the model.
    """

    name: str
    frame: str
    nq: int
    nv: int
    kind: np.ndarray
    axis_index: np.ndarray
    axis: np.ndarray
    idx_q: np.ndarray
    idx_v: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray
    frame_rotation: np.ndarray
    frame_translation: np.ndarray
    continuous_q: np.ndarray

    # -- construction ------------------------------------------------------------------------
    @classmethod
    def from_robot(cls, robot: Robot, frame: str | None = None) -> BatchedKinematics:
        """Compile `frame` (default: the tool frame) of a loaded robot."""
        fid = robot.frame_id(frame)
        return cls.from_model(robot.model, fid, robot.name)

    @classmethod
    def from_model(cls, model: pin.Model, frame_id: int, name: str = "model") -> BatchedKinematics:
        """Compile frame `frame_id` of a Pinocchio model.

        Raises:
            UnsupportedRobotError: a joint of the model is not one of `SUPPORTED`.
        """
        data = model.createData()
        pin.forwardKinematics(model, data, pin.neutral(model))
        continuous = []
        for jid in range(1, model.njoints):
            short = model.joints[jid].shortname()
            if short not in _KINDS:
                raise UnsupportedRobotError(
                    name,
                    f"joint {model.names[jid]!r} is a {short.removeprefix('JointModel')} joint; "
                    f"batched kinematics supports {SUPPORTED}",
                )
            if _KINDS[short] == CONTINUOUS:
                continuous.append(model.joints[jid].idx_q)
        chain = []
        jid = int(model.frames[frame_id].parentJoint)
        while jid > 0:
            chain.append(jid)
            jid = int(model.parents[jid])
        chain.reverse()
        kind, index, axes = [], [], []
        for jid in chain:
            k = _KINDS[model.joints[jid].shortname()]
            S = np.asarray(data.joints[jid].S).reshape(6)  # motion subspace in the joint frame
            a = S[:3] if k == PRISMATIC else S[3:]
            a = a / np.linalg.norm(a)
            hit = np.flatnonzero(np.abs(a) == 1.0)
            kind.append(k)
            index.append(int(hit[0]) if hit.size else -1)
            axes.append(a)
        placement = model.frames[frame_id].placement
        n = len(chain)
        return cls(
            name=name,
            frame=model.frames[frame_id].name,
            nq=int(model.nq),
            nv=int(model.nv),
            kind=np.array(kind, dtype=np.int64),
            axis_index=np.array(index, dtype=np.int64),
            axis=np.array(axes, dtype=float).reshape(n, 3),
            idx_q=np.array([model.joints[j].idx_q for j in chain], dtype=np.int64),
            idx_v=np.array([model.joints[j].idx_v for j in chain], dtype=np.int64),
            rotation=np.array([model.jointPlacements[j].rotation for j in chain], dtype=float).reshape(n, 3, 3),
            translation=np.array([model.jointPlacements[j].translation for j in chain], dtype=float).reshape(n, 3),
            frame_rotation=np.array(placement.rotation, dtype=float),
            frame_translation=np.array(placement.translation, dtype=float),
            continuous_q=np.array(continuous, dtype=np.int64),
        )

    # -- evaluation --------------------------------------------------------------------------
    def check_configurations(self, q: np.ndarray) -> np.ndarray:
        """q as a C-contiguous (N, nq) float array; raises `InvalidInputError` unless it is one
        (a single (nq,) configuration is accepted as N = 1), finite, with unit (cos, sin) pairs."""
        a = np.asarray(q, dtype=float)
        if a.ndim == 1:
            a = a[None, :]
        if a.ndim != 2 or a.shape[1] != self.nq:
            raise InvalidInputError(
                "q", f"{self.name}: expected Pinocchio configurations of shape (N, {self.nq}), got {np.shape(q)}"
            )
        # One sum is ~20x cheaper than a per-row isfinite; it overflows only for values near 1e308,
        # and then the exact per-row check runs and decides.
        if not math.isfinite(float(a.sum())) and not (finite := np.isfinite(a).all(axis=1)).all():
            row = int(np.flatnonzero(~finite)[0])
            raise InvalidInputError("q", f"must be finite; row {row} is {a[row].tolist()}")
        if self.continuous_q.size:
            c, s = a[:, self.continuous_q], a[:, self.continuous_q + 1]
            # cos^2 + sin^2 from np.cos/np.sin is 1 to a few ulp; 1e-9 only rejects non-rotations.
            off = np.abs(c * c + s * s - 1.0) > 1e-9
            if off.any():
                row, col = (int(x[0]) for x in np.nonzero(off))
                j = int(self.continuous_q[col])
                raise InvalidInputError(
                    "q", f"row {row}: a continuous joint's q[{j}:{j + 2}] must be (cos t, sin t) with unit norm, "
                    f"got {a[row, j:j + 2].tolist()}",
                )
        return np.ascontiguousarray(a)

    def _run(self, q: np.ndarray, rows: np.ndarray, J: np.ndarray, threads: int | None) -> None:
        args = (
            q, self.kind, self.axis_index, self.axis, self.idx_q, self.idx_v,
            np.array([np.array_equal(r, np.eye(3)) for r in self.rotation], dtype=np.bool_).reshape(-1),
            self.rotation, self.translation,
            self.frame_rotation, self.frame_translation, rows, J, J.shape[0] > 0,
        )
        with _threads(threads):
            _kernel(*args)

    def fk(self, q: np.ndarray, threads: int | None = None, out: np.ndarray | None = None) -> BatchedPoses:
        """World placement of the frame at each configuration.

        Args:
            q: (N, nq) Pinocchio configurations (continuous joints as cos t, sin t).
            threads: Numba threads (default: all).
            out: a C-contiguous (N, 12) float array to write the rows into (saves the allocation
                when a caller streams chunks through one buffer).

        Returns:
            positions [m] (N, 3), rotations (N, 3, 3) and both as (N, 12) rows.
        """
        a = self.check_configurations(q)
        if out is None:
            rows = np.empty((a.shape[0], 12))
        elif out.shape != (a.shape[0], 12) or out.dtype != np.float64 or not out.flags.c_contiguous:
            raise InvalidInputError("out", f"needs a C-contiguous float64 array of shape ({a.shape[0]}, 12)")
        else:
            rows = out
        self._run(a, rows, _NO_JACOBIAN, threads)
        return _poses(rows)

    def jacobian(self, q: np.ndarray, threads: int | None = None) -> np.ndarray:
        """(N, 6, nv) LOCAL_WORLD_ALIGNED frame Jacobians (linear rows [m/rad or 1], then angular)."""
        return self.fk_jacobian(q, threads)[1]

    def fk_jacobian(self, q: np.ndarray, threads: int | None = None) -> tuple[BatchedPoses, np.ndarray]:
        """Both `fk` and `jacobian` in one pass."""
        a = self.check_configurations(q)
        rows = np.empty((a.shape[0], 12))
        J = np.empty((a.shape[0], 6, self.nv))
        self._run(a, rows, J, threads)
        return _poses(rows), J


def _poses(rows: np.ndarray) -> BatchedPoses:
    return BatchedPoses(rows[:, :3], rows[:, 3:].reshape(-1, 3, 3), rows)


@contextmanager
def _threads(n: int | None) -> Iterator[None]:
    """Run Numba kernels on `n` threads inside the block (None: as configured)."""
    import numba

    saved = numba.get_num_threads()
    if n is not None:
        try:
            numba.set_num_threads(n)
        except ValueError as exc:  # not in 1..NUMBA_NUM_THREADS
            raise InvalidInputError("threads", str(exc)) from None
    try:
        yield
    finally:
        numba.set_num_threads(saved)


# -- convenience ----------------------------------------------------------------------------------
@functools.lru_cache(maxsize=64)
def compile_frame(robot: Robot, frame: str | None = None) -> BatchedKinematics:
    """`BatchedKinematics.from_robot`, cached per (robot, frame)."""
    return BatchedKinematics.from_robot(robot, frame)


def batched_fk(robot: Robot, q: np.ndarray, frame: str | None = None) -> BatchedPoses:
    """Placements of `frame` (default: the tool) at (N, nq) Pinocchio configurations q."""
    return compile_frame(robot, frame).fk(q)


def batched_jacobian(robot: Robot, q: np.ndarray, frame: str | None = None) -> np.ndarray:
    """(N, 6, nv) LOCAL_WORLD_ALIGNED Jacobians of `frame` at (N, nq) Pinocchio configurations q."""
    return compile_frame(robot, frame).jacobian(q)


def configurations(robot: Robot, values: np.ndarray, *, degrees: bool = False) -> np.ndarray:
    """(N, nq) Pinocchio configurations from (N, nv) joint values, one per degree of freedom
    ([rad] or [m]; a continuous joint's angle t becomes cos t, sin t) — `Robot.configuration`
    for many rows.

    Args:
        degrees: revolute and continuous values are in degrees (prismatic ones stay in metres).
    """
    v = np.array(values, dtype=float)
    if v.ndim == 1 and robot.nv == 1:
        v = v[:, None]
    if v.ndim != 2 or v.shape[1] != robot.nv:
        raise InvalidInputError(
            "joint values",
            f"{robot.name} needs rows of {robot.nv} values ({', '.join(robot.joint_names)}), got shape {np.shape(values)}",
        )
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise InvalidInputError("joint values", f"must be finite; row {row} is {v[row].tolist()}")
    q = np.empty((v.shape[0], robot.model.nq))
    q[:] = pin.neutral(robot.model)
    for i, d in enumerate(robot.dofs):
        x = np.radians(v[:, i]) if degrees and d.kind != "prismatic" else v[:, i]
        if d.kind == "continuous":
            q[:, d.idx_q], q[:, d.idx_q + 1] = np.cos(x), np.sin(x)
        else:
            q[:, d.idx_q] = x
    return q


# -- kernels --------------------------------------------------------------------------------------
def _split(x: Fraction, bits: int) -> Fraction:
    """x rounded to `bits` significant bits."""
    scale = Fraction(2) ** (bits - math.frexp(float(x))[1])
    return Fraction(round(x * scale)) / scale


_PI = Fraction(Decimal("3.14159265358979323846264338327950288419716939937510582097494459230781640629"))
# pi/2 = _P1 + _P2 + _P3 with _P1, _P2 of 33 significant bits: k * _P1 and k * _P2 are exact for
# |k| < 2**20, so the reduced argument r = x - k pi/2 is good to an ulp of r (Cody-Waite).
_H1 = _split(_PI / 2, 33)
_H2 = _split(_PI / 2 - _H1, 33)
_P1, _P2, _P3 = float(_H1), float(_H2), float(_PI / 2 - _H1 - _H2)
_TWO_OVER_PI = float(2 / _PI)
_REDUCE_MAX = 1e5  # |x| beyond this (k >= 2**16): libm's full reduction instead
# Taylor coefficients; on |r| <= pi/4 the first omitted terms r^19/19!, r^20/20! are < 1e-19.
_S = tuple((-1) ** k / math.factorial(2 * k + 1) for k in range(1, 9))
_C = tuple((-1) ** k / math.factorial(2 * k) for k in range(1, 10))


@njit(cache=True, inline="always")
def _sincos_reduced(x):  # pragma: no cover - compiled
    """(sin x, cos x) to ~1 ulp for |x| <= _REDUCE_MAX, without branches (so that loops over
    configurations vectorise): Cody-Waite reduction to |r| <= pi/4, Taylor polynomials, quadrant."""
    k = math.floor(x * _TWO_OVER_PI + 0.5)
    r = ((x - k * _P1) - k * _P2) - k * _P3
    z = r * r
    s = r + r * z * (_S[0] + z * (_S[1] + z * (_S[2] + z * (_S[3] + z * (_S[4] + z * (_S[5] + z * (
        _S[6] + z * _S[7])))))))
    c = 1.0 + z * (_C[0] + z * (_C[1] + z * (_C[2] + z * (_C[3] + z * (_C[4] + z * (_C[5] + z * (
        _C[6] + z * (_C[7] + z * _C[8]))))))))
    n = np.int64(k)  # quadrant: sin x = s, c, -s, -c and cos x = c, -s, -c, s for n = 0, 1, 2, 3 (mod 4)
    swap = (n & 1) == 1
    a = c if swap else s
    b = s if swap else c
    a = -a if (n & 2) else a
    b = -b if ((n + 1) & 2) else b
    return a, b


BLOCK = 256
"""Configurations carried through the chain together by one parallel work item."""


@njit(cache=True, parallel=True)
def _kernel(q, kind, aidx, axis, iq, iv, ident, rot, tra, fR, fp, rows, J, jac):  # pragma: no cover - compiled
    """Frame placements of every row of q into rows (N, 12) and, if `jac`, Jacobians into J.

    Organised for SIMD: a block of configurations is carried through the chain one joint at a
    time (state R, p as 12 rows of the block), so each step is a loop over configurations that the
    compiler vectorises; blocks run in parallel, each with its own small scratch.
    """
    N = q.shape[0]
    nj = kind.shape[0]
    B = BLOCK
    for blk in prange((N + B - 1) // B):
        n0 = blk * B
        m = min(B, N - n0)
        st = np.empty((12, B))  # R row-major, then p
        sn = np.empty(B)
        cs = np.empty(B)
        qt = np.empty((q.shape[1], B))  # the block's configurations, one row per coordinate
        W = np.empty((nj if jac else 0, 3, B))  # world axis of each joint
        P = np.empty((nj if jac else 0, 3, B))  # world origin of each joint
        for b in range(m):
            for c in range(q.shape[1]):
                qt[c, b] = q[n0 + b, c]
        for b in range(m):
            for r in range(12):
                st[r, b] = 0.0
            st[0, b] = 1.0
            st[4, b] = 1.0
            st[8, b] = 1.0
        for k in range(nj):
            # Joint placement M: p += R t, R = R M.
            tx, ty, tz = tra[k, 0], tra[k, 1], tra[k, 2]
            for b in range(m):
                st[9, b] += st[0, b] * tx + st[1, b] * ty + st[2, b] * tz
                st[10, b] += st[3, b] * tx + st[4, b] * ty + st[5, b] * tz
                st[11, b] += st[6, b] * tx + st[7, b] * ty + st[8, b] * tz
            if not ident[k]:  # most URDF joints have no rotation in their origin: skip R = R I
                for r in range(0, 9, 3):
                    for b in range(m):
                        a0, a1, a2 = st[r, b], st[r + 1, b], st[r + 2, b]
                        st[r, b] = a0 * rot[k, 0, 0] + a1 * rot[k, 1, 0] + a2 * rot[k, 2, 0]
                        st[r + 1, b] = a0 * rot[k, 0, 1] + a1 * rot[k, 1, 1] + a2 * rot[k, 2, 1]
                        st[r + 2, b] = a0 * rot[k, 0, 2] + a1 * rot[k, 1, 2] + a2 * rot[k, 2, 2]
            ax, ay, az = axis[k, 0], axis[k, 1], axis[k, 2]
            col = iq[k]
            if jac:
                # World axis R a (the joint's own motion leaves it unchanged) and origin.
                for b in range(m):
                    W[k, 0, b] = st[0, b] * ax + st[1, b] * ay + st[2, b] * az
                    W[k, 1, b] = st[3, b] * ax + st[4, b] * ay + st[5, b] * az
                    W[k, 2, b] = st[6, b] * ax + st[7, b] * ay + st[8, b] * az
                    P[k, 0, b], P[k, 1, b], P[k, 2, b] = st[9, b], st[10, b], st[11, b]
            if kind[k] == 2:  # prismatic: p += t R a
                for b in range(m):
                    t = qt[col, b]
                    st[9, b] += t * (st[0, b] * ax + st[1, b] * ay + st[2, b] * az)
                    st[10, b] += t * (st[3, b] * ax + st[4, b] * ay + st[5, b] * az)
                    st[11, b] += t * (st[6, b] * ax + st[7, b] * ay + st[8, b] * az)
                continue
            if kind[k] == 1:  # continuous: (cos t, sin t) from q, as Pinocchio
                for b in range(m):
                    cs[b] = qt[col, b]
                    sn[b] = qt[col + 1, b]
            else:
                big = 0.0
                for b in range(m):
                    big = max(big, abs(qt[col, b]))
                if big > _REDUCE_MAX:
                    for b in range(m):
                        sn[b], cs[b] = math.sin(qt[col, b]), math.cos(qt[col, b])
                else:
                    for b in range(m):
                        sn[b], cs[b] = _sincos_reduced(qt[col, b])
            i = aidx[k]
            if i >= 0:
                # About +-e_i: columns j, l (cyclic after i) turn by the angle, sign included.
                sign = ax + ay + az
                j = (i + 1) % 3
                l = (i + 2) % 3
                for r in range(0, 9, 3):
                    for b in range(m):
                        c, s = cs[b], sn[b] * sign
                        u, v = st[r + j, b], st[r + l, b]
                        st[r + j, b] = c * u + s * v
                        st[r + l, b] = c * v - s * u
            else:
                # R = R (c I + s [a]x + (1 - c) a a^T)
                for b in range(m):
                    c, s = cs[b], sn[b]
                    d = 1.0 - c
                    e00, e01, e02 = c + d * ax * ax, d * ax * ay - s * az, d * ax * az + s * ay
                    e10, e11, e12 = d * ay * ax + s * az, c + d * ay * ay, d * ay * az - s * ax
                    e20, e21, e22 = d * az * ax - s * ay, d * az * ay + s * ax, c + d * az * az
                    for r in range(0, 9, 3):
                        a0, a1, a2 = st[r, b], st[r + 1, b], st[r + 2, b]
                        st[r, b] = a0 * e00 + a1 * e10 + a2 * e20
                        st[r + 1, b] = a0 * e01 + a1 * e11 + a2 * e21
                        st[r + 2, b] = a0 * e02 + a1 * e12 + a2 * e22
        tx, ty, tz = fp[0], fp[1], fp[2]
        for b in range(m):
            n = n0 + b
            rows[n, 0] = st[9, b] + st[0, b] * tx + st[1, b] * ty + st[2, b] * tz
            rows[n, 1] = st[10, b] + st[3, b] * tx + st[4, b] * ty + st[5, b] * tz
            rows[n, 2] = st[11, b] + st[6, b] * tx + st[7, b] * ty + st[8, b] * tz
            for r in range(3):
                for c in range(3):
                    rows[n, 3 + 3 * r + c] = st[3 * r, b] * fR[0, c] + st[3 * r + 1, b] * fR[1, c] \
                        + st[3 * r + 2, b] * fR[2, c]
        if not jac:
            continue
        for b in range(m):
            n = n0 + b
            for r in range(6):
                for c in range(J.shape[2]):
                    J[n, r, c] = 0.0
            x, y, z = rows[n, 0], rows[n, 1], rows[n, 2]
            for k in range(nj):
                c = iv[k]
                wx, wy, wz = W[k, 0, b], W[k, 1, b], W[k, 2, b]
                if kind[k] == 2:
                    J[n, 0, c], J[n, 1, c], J[n, 2, c] = wx, wy, wz
                else:
                    dx, dy, dz = x - P[k, 0, b], y - P[k, 1, b], z - P[k, 2, b]
                    J[n, 0, c] = wy * dz - wz * dy
                    J[n, 1, c] = wz * dx - wx * dz
                    J[n, 2, c] = wx * dy - wy * dx
                    J[n, 3, c], J[n, 4, c], J[n, 5, c] = wx, wy, wz
