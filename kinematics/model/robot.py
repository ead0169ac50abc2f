"""Robot model loading: built-in robots, URDF paths and example-robot-data names.

A `Robot` bundles the Pinocchio model with what the rest of the toolkit needs to know about it:
its source file, a default tool frame, the per-degree-of-freedom joint table (names, limits) and,
for closed-loop mechanisms, the loop-closure sidecar (see `kinematics.model.loops`).

Resolution order for `load_robot(spec)`: a built-in name (`scara`, `p2us`, `p2us-results`, `delta`), an
existing path, an example-robot-data name (curated aliases such as `ur5`, `panda`, or any URDF
file stem in that package). Robots are loaded with a fixed base.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, NamedTuple

import numpy as np
import pinocchio as pin

from kinematics.errors import (
    InvalidInputError,
    MissingRangeError,
    ModelFileError,
    UnknownFrameError,
    UnknownJointError,
    UnknownRobotError,
    UnsupportedRobotError,
)
from kinematics.model.urdf_file import build_model, check_urdf_file, missing_range_sides, read_urdf

__all__ = ["BUILTIN", "ERD_ALIASES", "URDF_DIR", "Dof", "ParserAgreement", "Robot", "apply_ranges", "build_model",
           "check_urdf_file", "erd_catalogue", "erd_robots_dir", "load_robot", "matrix", "missing_range_sides",
           "parser_agreement", "robot_names", "urdf_in"]

if TYPE_CHECKING:  # pragma: no cover
    from kinematics.model.loops import LoopSpec

def _urdf_dir() -> Path:
    package = Path(__file__).resolve().parent.parent  # kinematics/
    installed = package / "urdf"  # a wheel maps the repository's urdf/ to kinematics/urdf
    return installed if installed.is_dir() else package.parent / "urdf"


URDF_DIR = _urdf_dir()
"""Where the built-in URDFs live (the repository's top-level `urdf/`)."""

BUILTIN = {"scara": "scara.urdf", "p2us": "p2us.urdf", "p2us-results": "p2us-results.urdf",
           "delta": "delta.urdf"}
"""Built-in robots: name -> file in `URDF_DIR`."""

ERD_ALIASES = {
    "ur3": "ur_description/urdf/ur3_robot.urdf",
    "ur5": "ur_description/urdf/ur5_robot.urdf",
    "ur10": "ur_description/urdf/ur10_robot.urdf",
    "panda": "panda_description/urdf/panda.urdf",
    "z1": "z1_description/urdf/z1.urdf",
    "xarm7": "xarm_description/urdf/xarm7.urdf",
    "kinova": "kinova_description/robots/kinova.urdf",
    "so100": "so_arm_description/urdf/so100.urdf",
    "double_pendulum": "double_pendulum_description/urdf/double_pendulum.urdf",
    "finger_edu": "finger_edu_description/robots/finger_edu.urdf",
}
"""Short names for arms shipped by example-robot-data (paths relative to its `robots/`)."""

JointKind = Literal["revolute", "prismatic", "continuous"]


def matrix(J: object, ncols: int) -> np.ndarray:
    """A Pinocchio matrix as a 2-D array with `ncols` columns: Pinocchio's Python bindings
    return an n x 1 matrix (a 1-DOF robot's Jacobian) as a 1-D array."""
    a = np.asarray(J)
    if a.ndim == 2 and a.shape[1] == ncols:  # an n x 0 one too, whose row count -1 cannot infer from size 0
        return a
    return a.reshape(-1, ncols)


class Dof(NamedTuple):
    """One degree of freedom: joint name, kind, indices into q and v, limits [rad] or [m].

    A side of the range that the URDF does not give (a `<limit>` without `lower` or `upper`) is
    -inf or +inf: no range is never read as [0, 0].
    """

    name: str
    kind: JointKind
    idx_q: int
    idx_v: int
    lower: float
    upper: float

    @property
    def range_given(self) -> bool:
        """True for a continuous joint (a full turn by definition) or a finite [lower, upper]."""
        return self.kind == "continuous" or bool(np.isfinite(self.lower) and np.isfinite(self.upper))


@dataclass(frozen=True, eq=False)
class Robot:
    """A loaded robot. Build with `load_robot`; the fields are read-only."""

    name: str
    urdf_path: Path
    model: pin.Model
    tool_frame: str
    package_dirs: tuple[str, ...] = ()
    loops: LoopSpec | None = None
    dofs: tuple[Dof, ...] = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "dofs", _dof_table(self.name, self.model))

    # -- names -------------------------------------------------------------------------------
    @property
    def nv(self) -> int:
        """Number of degrees of freedom (velocity dimension)."""
        return int(self.model.nv)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of the moving joints, one per degree of freedom, in model order."""
        return tuple(d.name for d in self.dofs)

    @property
    def frame_names(self) -> tuple[str, ...]:
        """All frame names of the Pinocchio model (links, joints, fixed joints)."""
        return tuple(dict.fromkeys(f.name for f in self.model.frames))

    def frame_id(self, name: str | None = None) -> int:
        """Index of frame `name` (default: the tool frame); raises `UnknownFrameError`."""
        name = self.tool_frame if name is None else name
        ids = [i for i, f in enumerate(self.model.frames) if f.name == name]
        if not ids:
            raise UnknownFrameError(name, self.frame_names)
        # A joint and a link may share a name: the link (BODY) frame is the one meant.
        body = [i for i in ids if self.model.frames[i].type == pin.FrameType.BODY]
        return (body or ids)[0]

    @property
    def unranged(self) -> tuple[str, ...]:
        """Joints whose URDF gives no range (or only one side of it), in model order."""
        return tuple(d.name for d in self.dofs if not d.range_given)

    def require_ranges(self, joints: Sequence[str], purpose: str) -> None:
        """Raise `MissingRangeError` naming those of `joints` that have no range.

        Args:
            joints: joint names the caller needs bounded.
            purpose: what needs them, for the message (e.g. "a workspace").
        """
        missing = [n for n in self.unranged if n in set(joints)]
        if missing:
            raise MissingRangeError(self.name, missing, purpose)

    @property
    def lower(self) -> np.ndarray:
        """Lower joint limits per degree of freedom [rad] or [m] (-inf if unbounded)."""
        return np.array([d.lower for d in self.dofs])

    @property
    def upper(self) -> np.ndarray:
        """Upper joint limits per degree of freedom [rad] or [m] (+inf if unbounded)."""
        return np.array([d.upper for d in self.dofs])

    @functools.cached_property
    def data(self) -> pin.Data:
        """A scratch `pin.Data` owned by this robot (not thread-safe: one per thread)."""
        return self.model.createData()

    # -- configurations ----------------------------------------------------------------------
    def joint_values(self, values: Sequence[float] | np.ndarray, *, degrees: bool = False) -> np.ndarray:
        """Validate one value per degree of freedom and return them as an array.

        Args:
            values: joint values in model order, [rad] for revolute joints, [m] for prismatic.
            degrees: the revolute values are in degrees (prismatic ones stay in metres).
        """
        v = np.array(values, dtype=float).reshape(-1)
        if v.size != self.nv:
            raise InvalidInputError(
                "joint values",
                f"{self.name} has {self.nv} degrees of freedom ({', '.join(self.joint_names)}), "
                f"got {v.size} value(s)",
            )
        bad = ~np.isfinite(v)
        if bad.any():
            names = [self.dofs[i].name for i in np.flatnonzero(bad)]
            raise InvalidInputError("joint values", f"must be finite; got {v[bad].tolist()} for {names}")
        if degrees:
            angular = np.array([d.kind != "prismatic" for d in self.dofs])
            v[angular] = np.radians(v[angular])
        return v

    def configuration(self, values: Sequence[float] | np.ndarray, *, degrees: bool = False) -> np.ndarray:
        """Pinocchio configuration vector q from one value per degree of freedom."""
        v = self.joint_values(values, degrees=degrees)
        q = pin.neutral(self.model)
        for d, x in zip(self.dofs, v, strict=True):
            if d.kind == "continuous":
                q[d.idx_q : d.idx_q + 2] = np.cos(x), np.sin(x)
            else:
                q[d.idx_q] = x
        return q

    def check_configuration(self, q: Sequence[float] | np.ndarray) -> np.ndarray:
        """One Pinocchio configuration as a float array (nq,) (a (1, nq) row is accepted): raises
        InvalidInputError unless it has nq finite values (nq: one per degree of freedom, two
        (cos, sin) per continuous joint; `configuration` builds one from joint values)."""
        try:
            a = np.array(q, dtype=float)
        except (TypeError, ValueError):
            raise InvalidInputError("q", f"expected {self.model.nq} numbers, got {q!r}") from None
        if a.ndim > 2 or a.size != self.model.nq or (a.ndim == 2 and len(a) != 1):
            raise InvalidInputError("q", f"{self.name} takes a Pinocchio configuration of {self.model.nq} values "
                                         f"(nq; joint values give one with configuration()), got shape {a.shape}")
        a = a.reshape(-1)
        if not np.isfinite(a).all():
            raise InvalidInputError("q", f"must be finite; got {a.tolist()}")
        return a

    def values_from_configuration(self, q: np.ndarray) -> np.ndarray:
        """Inverse of `configuration`: one value per degree of freedom."""
        out = np.empty(self.nv)
        for i, d in enumerate(self.dofs):
            if d.kind == "continuous":
                out[i] = np.arctan2(q[d.idx_q + 1], q[d.idx_q])
            else:
                out[i] = q[d.idx_q]
        return out

    def within_limits(self, values: np.ndarray, tol: float = 0.0) -> np.ndarray:
        """Per-degree-of-freedom flag: lower - tol <= value <= upper + tol."""
        v = np.asarray(values, dtype=float)
        return (v >= self.lower - tol) & (v <= self.upper + tol)


def _dof_table(robot: str, model: pin.Model) -> tuple[Dof, ...]:
    dofs = []
    for jid in range(1, model.njoints):
        joint = model.joints[jid]
        short = joint.shortname()
        name = model.names[jid]
        if joint.nq == 1 and joint.nv == 1:
            kind: JointKind = "prismatic" if short.removeprefix("JointModel").startswith("P") else "revolute"
            lo = float(model.lowerPositionLimit[joint.idx_q])
            hi = float(model.upperPositionLimit[joint.idx_q])
        elif joint.nq == 2 and joint.nv == 1:
            kind, lo, hi = "continuous", -np.inf, np.inf
        else:
            raise UnsupportedRobotError(robot, f"joint {name!r} ({short}) is not a 1-DOF joint")
        dofs.append(Dof(name, kind, joint.idx_q, joint.idx_v, lo, hi))
    return tuple(dofs)


# -- resolution --------------------------------------------------------------------------------
def apply_ranges(model: pin.Model, missing: dict[str, tuple[bool, bool]],
                 ranges: Mapping[str, tuple[float, float]] | None = None) -> None:
    """Set `model`'s position limits in place: +/-inf on each side in `missing`, then each joint
    of `ranges` (name -> (lower, upper) [rad or m]) to its given range.

    Raises:
        UnknownJointError: a name in `ranges` is not a 1-DOF joint of the model.
        InvalidInputError: a range that is not finite with lower < upper.
    """
    lo = np.array(model.lowerPositionLimit, dtype=float)
    hi = np.array(model.upperPositionLimit, dtype=float)
    index = {model.names[j]: model.joints[j].idx_q for j in range(1, model.njoints)
             if model.joints[j].nq == 1 and model.joints[j].nv == 1}
    for name, (no_lo, no_hi) in missing.items():
        if name in index:
            lo[index[name]] = -np.inf if no_lo else lo[index[name]]
            hi[index[name]] = np.inf if no_hi else hi[index[name]]
    for name, pair in (ranges or {}).items():
        if name not in index:
            raise UnknownJointError(name, list(index))
        try:
            a, b = (float(v) for v in pair)
        except (TypeError, ValueError):  # not a pair of numbers: a number, a triple, text
            raise InvalidInputError(f"range of {name}", f"expected a pair (LO, HI) of numbers [rad or m], got {pair!r}") from None
        if not (np.isfinite(a) and np.isfinite(b) and a < b):
            raise InvalidInputError(f"range of {name}", f"expected finite LO < HI, got [{a}, {b}]")
        lo[index[name]], hi[index[name]] = a, b
    model.lowerPositionLimit = lo
    model.upperPositionLimit = hi


def urdf_in(directory: Path) -> Path:
    """The URDF of a model folder (as Gepetto's loaders take it): `robot.urdf`, else its only
    `*.urdf` file.

    Raises:
        ModelFileError: the folder holds no URDF, or several and none is `robot.urdf`.
    """
    if (directory / "robot.urdf").is_file():
        return directory / "robot.urdf"
    found = sorted(directory.glob("*.urdf"))
    if len(found) == 1:
        return found[0]
    if not found:
        raise ModelFileError(directory, "a folder with no .urdf file in it")
    raise ModelFileError(directory, f"a folder with {len(found)} URDF files and no robot.urdf; name one of: "
                                    f"{', '.join(f.name for f in found)}")


@functools.cache
def erd_robots_dir() -> Path | None:
    """The `robots/` folder of the installed example-robot-data package, if any."""
    import importlib.metadata  # ~14 ms at start-up otherwise: only when a name is not built in

    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        return None
    root = Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))
    return root if root.is_dir() else None


@functools.cache
def erd_catalogue() -> dict[str, Path]:
    """example-robot-data names -> URDF path: curated aliases, then every URDF file stem."""
    root = erd_robots_dir()
    if root is None:
        return {}
    names = {p.stem: p for p in sorted(root.glob("*/*/*.urdf"))}
    names.update({k: root / v for k, v in ERD_ALIASES.items() if (root / v).exists()})
    return names


def robot_names() -> tuple[str, ...]:
    """Every name `load_robot` accepts besides file paths: built-ins, aliases, then the rest."""
    aliases = [k for k in ERD_ALIASES if k in erd_catalogue()]
    rest = sorted(set(erd_catalogue()) - set(aliases))
    return (*BUILTIN, *aliases, *rest)


def _default_tool_frame(model: pin.Model) -> str:
    """The last body frame; where no joint moves it (a tree whose file ends with a sensor on the
    base, e.g. tiago's laser), the last body of the chain with the most moving joints."""
    bodies = [f for f in model.frames if f.type == pin.FrameType.BODY]
    if not bodies:
        return str(model.frames[-1].name)

    def moving_joints(j: int) -> int:
        n = 0
        while j > 0:
            n += model.joints[j].nv > 0
            j = model.parents[j]
        return n

    depth = [moving_joints(f.parentJoint) for f in bodies]
    if depth[-1] > 0:
        return str(bodies[-1].name)
    return str(bodies[max(range(len(bodies)), key=lambda k: (depth[k], k))].name)


def load_robot(spec: str | os.PathLike[str], *, tool_frame: str | None = None,
               ranges: Mapping[str, tuple[float, float]] | None = None) -> Robot:
    """Load a robot from a built-in name, a URDF path, a model folder or an example-robot-data name.

    A loop-closure sidecar next to the URDF (`<stem>.loops.yaml`) is loaded too; failing that, a
    Gepetto-format `robot.yaml` in the same folder (see `kinematics.model.gepetto`), whose joint
    substitutions change the model built from the URDF. A folder stands for its `robot.urdf` (or
    its only URDF) and names the robot.

    A joint whose `<limit>` gives no `lower`/`upper` has no range on that side (-inf/+inf, see
    `missing_range_sides`), never [0, 0]; `ranges` (joint -> (lower, upper) [rad or m]) gives or
    replaces ranges, after the sidecar's `ranges:`. `tool_frame` replaces the tool frame (an open
    chain's) or the end effector (a closed loop's, the sidecar's `end_effector`; not for a sidecar
    that names a closed-form `mechanism:`, whose platform frame the dispatcher holds it to).

    Raises:
        InvalidInputError: `spec` is neither text nor a path.
        UnknownRobotError: `spec` is no known name and no existing file.
        ModelFileError: the file is missing or malformed.
        UnknownFrameError: `tool_frame` is not in the model.
        UnknownJointError: `ranges` names a joint the model does not have.
    """
    if not isinstance(spec, (str, os.PathLike)):
        raise InvalidInputError("robot", f"expected a name, a URDF path or a model folder, got {type(spec).__name__} "
                                         f"{spec!r}")
    text = os.fspath(spec)
    if not isinstance(text, str):  # a PathLike of bytes
        raise InvalidInputError("robot", f"expected a text path, got {text!r}")
    package_dirs: tuple[str, ...] = ()
    if not text.strip():
        raise UnknownRobotError(text, robot_names())
    if text in BUILTIN:
        path, name = URDF_DIR / BUILTIN[text], text
    elif Path(text).is_dir():
        path, name = urdf_in(Path(text)), Path(text).resolve().name
    elif Path(text).suffix.lower() in (".urdf", ".xml") or os.sep in text or Path(text).exists():
        path, name = Path(text), Path(text).stem
    elif text in erd_catalogue():
        path, name = erd_catalogue()[text], text
        package_dirs = (str(erd_robots_dir().parent.parent),)  # type: ignore[union-attr]
    else:
        raise UnknownRobotError(text, robot_names())
    from kinematics.model.loops import find_loop_spec, sidecar_for

    gepetto = None
    if not sidecar_for(Path(path)).exists():  # our own sidecar wins over a Gepetto robot.yaml
        from kinematics.model.gepetto import find_gepetto

        gepetto = find_gepetto(path)
    if gepetto is not None:
        from kinematics.model import gepetto as gp

        model, root = gp.build_model(path, gepetto)
        loops: LoopSpec | None = gp.loop_spec(gepetto, model, tool_frame)
        if name == "robot":  # Gepetto's files are all robot.urdf: the folder names the robot
            name = Path(path).resolve().parent.name
    else:
        model, root = read_urdf(path)
        loops = find_loop_spec(path, model)
    given = {**(loops.ranges if loops is not None else {}), **(ranges or {})}
    apply_ranges(model, missing_range_sides(root), given)
    frame = tool_frame or (loops.end_effector if loops is not None else _default_tool_frame(model))
    if tool_frame is not None and loops is not None and loops.mechanism is None and loops.end_effector != tool_frame:
        import dataclasses

        loops = dataclasses.replace(loops, end_effector=tool_frame)
    robot = Robot(name, Path(path), model, frame, package_dirs, loops)
    robot.frame_id(frame)  # validate
    return robot


# -- second, independent parser ---------------------------------------------------------------
class ParserAgreement(NamedTuple):
    """Largest disagreement between Pinocchio and yourdfpy over all link frames."""

    frames: int
    max_position_error: float  # [m]
    max_rotation_error: float  # [rad]


def parser_agreement(robot: Robot, values: np.ndarray | None = None) -> ParserAgreement:
    """Compare every link placement computed by Pinocchio and by yourdfpy at `values`.

    Mimic joints are driven by yourdfpy from their master; Pinocchio (which loads them as
    independent joints) is given the same mimicked value.
    """
    import yourdfpy

    urdf: Any = yourdfpy.URDF.load(str(robot.urdf_path), build_scene_graph=True, load_meshes=False)
    v = np.zeros(robot.nv) if values is None else robot.joint_values(values)
    by_name = dict(zip(robot.joint_names, v, strict=True))
    cfg = {n: by_name[n] for n in urdf.actuated_joint_names if n in by_name}
    urdf.update_cfg(cfg)
    for name, joint in urdf.joint_map.items():
        if joint.mimic is not None and name in by_name:
            by_name[name] = joint.mimic.multiplier * by_name[joint.mimic.joint] + joint.mimic.offset
    q = robot.configuration([by_name[n] for n in robot.joint_names])
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    dp = dr = 0.0
    count = 0
    for link in urdf.link_map:
        if not robot.model.existFrame(link, pin.FrameType.BODY):
            continue
        T = urdf.get_transform(link)
        M = data.oMf[robot.model.getFrameId(link, pin.FrameType.BODY)]
        dp = max(dp, float(np.linalg.norm(T[:3, 3] - M.translation)))
        dr = max(dr, float(np.linalg.norm(pin.log3(T[:3, :3].T @ M.rotation))))
        count += 1
    return ParserAgreement(count, dp, dr)
