"""Loop-closure sidecars: what a URDF tree cannot say about a closed-loop mechanism.

A sidecar `<robot>.loops.yaml` sits next to `<robot>.urdf` (in the spirit of Gepetto's
`robot.yaml`)::

    format: kinematics-loops/1
    mechanism: 3-[P2(US)]            # optional: enables that mechanism's closed forms
    end_effector: platform           # frame whose pose the mechanism controls
    actuated: [slider_1, slider_2, slider_3]
    closures:                        # pairs of frames that must coincide
      - {name: S_1_2, type: point, frame1: tip_1_2, frame2: anchor_1_2}   # 3 equations
      - {name: W, type: 6d, frame1: a, frame2: b}                         # 6 equations (weld)
    reference: {slider_1: 0.24, ...} # optional: an assembled configuration (the solver's start)
    ranges: {slider_1: [0.1, 0.5]}   # optional: joint ranges [rad or m] the URDF does not give
    collisions:                      # optional: as an SRDF's disabled collisions
      disabled: [[rod_1_1, rod_1_2]] # link pairs never checked for collision
      sizes: {rod_radius: 0.006}     # generated files: the collision shapes' sizes [m], a record

`point` closes a spherical joint (positions equal), `6d` a rigid weld (placements equal).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import pinocchio as pin

from kinematics.errors import InvalidInputError, ModelFileError, UnknownFrameError, UnknownJointError
from kinematics.files import read_text

ClosureType = Literal["point", "6d"]
CLOSURE_TYPES: tuple[str, ...] = ("point", "6d")
FORMAT = "kinematics-loops/1"


@dataclass(frozen=True)
class Closure:
    """Two frames that coincide when the loop is closed."""

    name: str
    frame1: str
    frame2: str
    type: ClosureType = "point"

    @property
    def size(self) -> int:
        """Number of scalar equations."""
        return 3 if self.type == "point" else 6


@dataclass(frozen=True)
class LoopSpec:
    """The parsed sidecar of a closed-loop robot."""

    path: Path
    actuated: tuple[str, ...]
    closures: tuple[Closure, ...]
    end_effector: str
    mechanism: str | None = None
    reference: dict[str, float] = field(default_factory=dict)
    ranges: dict[str, tuple[float, float]] = field(default_factory=dict)
    disabled_collisions: tuple[tuple[str, str], ...] = ()

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready summary."""
        return {
            "sidecar": str(self.path),
            "mechanism": self.mechanism,
            "end_effector": self.end_effector,
            "actuated": list(self.actuated),
            "constraints": [
                {"name": c.name, "type": c.type, "frame1": c.frame1, "frame2": c.frame2} for c in self.closures
            ],
        }


def sidecar_for(urdf_path: Path) -> Path:
    """`robot.urdf` -> `robot.loops.yaml`."""
    return urdf_path.with_name(urdf_path.stem + ".loops.yaml")


def find_loop_spec(urdf_path: Path, model: pin.Model) -> LoopSpec | None:
    """The sidecar next to `urdf_path`, parsed and checked against `model`; None if absent."""
    path = sidecar_for(Path(urdf_path))
    return load_loop_spec(path, model) if path.exists() else None


def load_loop_spec(path: Path, model: pin.Model) -> LoopSpec:
    """Parse and validate a sidecar: every frame and joint it names must exist in `model`."""
    import yaml

    try:
        raw = yaml.safe_load(read_text(path))
    except yaml.YAMLError as exc:
        raise ModelFileError(path, f"malformed YAML ({str(exc).splitlines()[0]})") from None
    if not isinstance(raw, dict):
        raise ModelFileError(path, "expected a mapping at the top level")
    if raw.get("format", FORMAT) != FORMAT:
        raise ModelFileError(path, f"unsupported format {raw.get('format')!r}; expected {FORMAT!r}")
    for key in ("actuated", "closures", "end_effector"):
        if key not in raw:
            raise ModelFileError(path, f"missing key {key!r}")
    frames = [f.name for f in model.frames]
    joints = list(model.names)[1:]

    def frame(name: Any) -> str:
        if not isinstance(name, str) or not model.existFrame(name):
            raise UnknownFrameError(str(name), frames)
        return name

    actuated = tuple(str(a) for a in raw["actuated"])
    for a in actuated:
        if a not in joints:
            raise UnknownJointError(a, joints)
    closures = []
    for k, c in enumerate(raw["closures"] or []):
        if not isinstance(c, dict) or "frame1" not in c or "frame2" not in c:
            raise ModelFileError(path, f"closure #{k + 1} needs frame1 and frame2")
        kind = c.get("type", "point")
        if kind not in CLOSURE_TYPES:
            raise ModelFileError(path, f"closure #{k + 1}: unknown type {kind!r}; valid: {', '.join(CLOSURE_TYPES)}")
        closures.append(Closure(str(c.get("name", f"closure_{k + 1}")), frame(c["frame1"]), frame(c["frame2"]), kind))
    reference = {}
    for name, value in (raw.get("reference") or {}).items():
        if name not in joints:
            raise UnknownJointError(str(name), joints)
        try:
            reference[str(name)] = float(value)
        except (TypeError, ValueError):
            raise InvalidInputError(f"reference {name}", f"not a number: {value!r}") from None
    ranges = {}
    raw_ranges = raw.get("ranges") or {}
    if not isinstance(raw_ranges, dict):
        raise ModelFileError(path, f"ranges: expected a mapping joint: [lower, upper], got {raw_ranges!r}")
    for name, pair in raw_ranges.items():
        if name not in joints:
            raise UnknownJointError(str(name), joints)
        try:
            lo, hi = (float(v) for v in pair)
        except (TypeError, ValueError):
            raise InvalidInputError(f"ranges {name}", f"expected [lower, upper], got {pair!r}") from None
        ranges[str(name)] = (lo, hi)
    return LoopSpec(
        disabled_collisions=_disabled_pairs(path, raw.get("collisions"), model),
        path=Path(path),
        actuated=actuated,
        closures=tuple(closures),
        end_effector=frame(raw["end_effector"]),
        mechanism=raw.get("mechanism"),
        reference=reference,
        ranges=ranges,
    )


def _disabled_pairs(path: Path, block: Any, model: pin.Model) -> tuple[tuple[str, str], ...]:
    """The `collisions: disabled:` link pairs of a sidecar, each link checked against `model`."""
    if block is None:
        return ()
    if not isinstance(block, dict):
        raise ModelFileError(path, f"collisions: expected a mapping (disabled, sizes), got {block!r}")
    links = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
    out = []
    disabled = block.get("disabled") or []
    if not isinstance(disabled, list):
        raise ModelFileError(path, f"collisions: disabled: expected a list of [link, link] pairs, got {disabled!r}")
    for pair in disabled:
        if not (isinstance(pair, list) and len(pair) == 2 and all(isinstance(x, str) for x in pair)):
            raise ModelFileError(path, f"collisions: disabled: expected [link, link] pairs, got {pair!r}")
        for name in pair:
            if name not in links:
                raise UnknownFrameError(name, links)
        out.append((pair[0], pair[1]))
    return tuple(out)
