"""Loop-closure sidecars for closed-loop mechanisms (filled in with the parallel robot)."""

from __future__ import annotations

from pathlib import Path

import pinocchio as pin


class LoopSpec:
    """Placeholder type; the sidecar format arrives with the parallel robot."""


def find_loop_spec(urdf_path: Path, model: pin.Model) -> LoopSpec | None:
    """The loop sidecar next to `urdf_path`, if there is one."""
    return None
