"""Error types. Everything the toolkit raises on bad input derives from `KinematicsError`.

Each subclass carries the offending value and, where there is a closed set of valid choices,
the choices themselves, so a caller (or the CLI) can say what would have worked.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence


def _choices(valid: Iterable[str], limit: int = 60) -> str:
    names = list(valid)
    shown = ", ".join(names[:limit])
    if len(names) > limit:
        shown += f", ... ({len(names) - limit} more)"
    return shown


def closest(name: str, valid: Iterable[str], n: int = 3) -> tuple[str, ...]:
    """The names of `valid` nearest `name` by `difflib`'s similarity ratio (>= 0.6), best first:
    what a misspelt joint, frame or robot name was most likely meant to be."""
    import difflib

    return tuple(difflib.get_close_matches(name, list(valid), n=n, cutoff=0.6))


class KinematicsError(Exception):
    """Root of every error the toolkit raises on purpose."""


class KinematicsWarning(UserWarning):
    """Something the toolkit did differently from what a file asked, and went on (e.g. a Gepetto
    `robot.yaml` substitution naming a joint the URDF lacks, left out as Gepetto's loader does).
    The command line prints each as one `warning:` line on stderr."""


class InvalidInputError(KinematicsError, ValueError):
    """A numeric input is malformed: wrong length, NaN/inf, out of a declared domain."""

    def __init__(self, what: str, problem: str) -> None:
        self.what = what
        self.problem = problem
        super().__init__(f"{what}: {problem}")


class UnknownNameError(KinematicsError, LookupError):
    """A name that must come from a closed set does not (robot, frame, mode, parameter...)."""

    kind = "name"

    def __init__(self, name: str, valid: Sequence[str], owner: str = "this robot") -> None:
        self.name = name
        self.valid = tuple(valid)
        self.closest = closest(name, self.valid)
        hint = f" (did you mean {' or '.join(map(repr, self.closest))}?)" if self.closest else ""
        # an empty set is said in words (e.g. a serial arm's working modes), not as "valid: " and nothing
        shown = _choices(self.valid) if self.valid else f"none ({owner} has no {self.kind} to choose)"
        super().__init__(f"unknown {self.kind} {name!r}{hint}; valid: {shown}")


class UnknownRobotError(UnknownNameError):
    """A robot name that is neither built in, nor in example-robot-data, nor a file."""

    kind = "robot"


class UnknownFrameError(UnknownNameError):
    """A frame name absent from the model."""

    kind = "frame"


class UnknownJointError(UnknownNameError):
    """A joint name absent from the model."""

    kind = "joint"


class UnknownModeError(UnknownNameError):
    """A working/assembly mode label that does not exist for this mechanism."""

    kind = "mode"


class UnknownChoiceError(UnknownNameError):
    """An option value outside its closed set (e.g. --limits)."""

    kind = "choice"


class UnknownParameterError(UnknownNameError):
    """A design parameter name that the generator or sweep does not know."""

    kind = "parameter"


class ModelFileError(KinematicsError, OSError):
    """A robot description file is missing, unreadable or malformed."""

    def __init__(self, path: object, problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


class UnsupportedRobotError(KinematicsError):
    """The operation needs a kind of mechanism this robot is not (e.g. a planar 2R arm)."""

    def __init__(self, robot: str, problem: str) -> None:
        self.robot = robot
        self.problem = problem
        super().__init__(f"{robot}: {problem}")


class ConvergenceError(KinematicsError, ArithmeticError):
    """An iterative solver stopped without meeting its tolerance."""

    def __init__(self, what: str, iterations: int, residual: float, tolerance: float, why: str | None = None) -> None:
        self.what = what
        self.iterations = iterations
        self.residual = residual
        self.tolerance = tolerance
        self.why = why
        """Why it stopped, where that is not a residual above the tolerance (None: it is)."""
        reason = why if why is not None else f"residual {residual:.3g} > tolerance {tolerance:.3g}"
        super().__init__(f"{what} did not converge: {reason} after {iterations} iterations")


class SingularConfigurationError(KinematicsError, ArithmeticError):
    """The requested quantity does not exist at a singular configuration."""

    def __init__(self, what: str, detail: str) -> None:
        self.what = what
        self.detail = detail
        super().__init__(f"{what}: {detail}")


class InvalidDesignError(InvalidInputError):
    """A design parameter that makes the mechanism degenerate (coincident limbs, a platform as
    wide as its base, a rail angle outside its range...)."""

    def __init__(self, parameter: str, value: object, reason: str) -> None:
        self.parameter = parameter
        self.value = value
        self.reason = reason
        super().__init__(parameter, f"{reason}; got {value}")


class SweepError(KinematicsError):
    """A design of a sweep failed on the cluster; the message names the design and the cause."""


class MissingCapabilityError(UnsupportedRobotError):
    """A command needs something the robot's mechanism does not provide (e.g. a workspace margin
    for a generic closed-loop model). Carries what was needed and what the mechanism has."""

    def __init__(self, robot: str, capability: str, purpose: str, available: Iterable[str]) -> None:
        self.capability = capability
        self.purpose = purpose
        self.available = tuple(sorted(available))
        super().__init__(robot, f"{purpose} needs its mechanism's {capability}, which this robot does not provide "
                                f"(it provides: {', '.join(self.available) or 'nothing'})")


class MissingRangeError(UnsupportedRobotError):
    """A command needs the range of joints whose URDF `<limit>` gives none (no `lower`/`upper`).

    Attributes:
        joints: the joints that lack a range, in model order.
        purpose: what needed them.
    """

    def __init__(self, robot: str, joints: Sequence[str], purpose: str) -> None:
        self.joints = tuple(joints)
        self.purpose = purpose
        example = " ".join(f"--range {j}=LO:HI" for j in self.joints[:2])
        super().__init__(robot, f"{purpose} needs the range of {', '.join(self.joints)}, which the URDF does not give "
                                f"(its <limit> has no lower/upper, or lower = upper); give them on the command line ({example}, "
                                "in rad or m), as `ranges:` in a loop sidecar, or as load_robot(..., ranges=...)")
