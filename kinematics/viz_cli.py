"""`kinematics show`: a Meshcat view of a robot with overlays, served live or exported as HTML."""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np

from .errors import InvalidInputError
from .report import Out


def run(args: argparse.Namespace, robot: Any, out: Out) -> int:
    import signal
    import sys

    from . import viz
    from .parallel_cli import _is_p2us

    if not args.export:
        # SIGTERM must end the meshcat server too (it outlives its parent otherwise)
        signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt()))
    scene = viz.Scene(live=not args.export)
    try:
        if _is_p2us(robot):
            if args.guide is not None:
                raise InvalidInputError("--guide", "guidance runs are for planar arms")
            actuators = None
            if args.q is not None:
                if len(args.q) != 3:
                    raise InvalidInputError("--q", f"give the 3 actuator values [m], got {len(args.q)}")
                actuators = np.array(args.q, dtype=float)
            viz.p2us_view(robot, None if args.position is None else np.array(args.position), args.mode or "---",
                          actuators, ellipsoid=args.ellipsoid, workspace=args.workspace,
                          singularities=args.singularities, limits=args.limits, step=args.step, scene=scene)
        elif robot.loops is None:
            if args.position is not None:
                raise InvalidInputError("--position", "give a serial robot's joint values with --q")
            q = robot.values_from_configuration(robot.configuration(args.q, degrees=args.degrees)) \
                if args.q is not None else None
            if _planar(robot):
                viz.scara_view(robot, q, ellipse=args.ellipsoid, workspace=args.workspace,
                               singularities=args.singularities, guide=args.guide, scene=scene)
            else:
                if args.workspace or args.singularities or args.guide is not None:
                    raise InvalidInputError("--workspace/--singularities/--guide",
                                            "available for the planar arm and the 3-[P2(US)]")
                viz.serial_view(robot, q, ellipsoid=args.ellipsoid, scene=scene)
        else:
            from .closedloop import ClosedLoop

            loop = ClosedLoop(robot)
            sol = loop.solve(np.array(args.q, dtype=float)) if args.q is not None else None
            scene.add_robot(robot, loop.reference if sol is None else sol.q)
            scene.fit_camera()
        print("".join(f"warning: {w}\n" for w in scene.warnings) + "".join(f"  not drawn: {s}\n" for s in scene.skipped),
              end="", file=sys.stderr)
        notes = {"warnings": scene.warnings, "skipped_visuals": scene.skipped}
        if args.export:
            scene.export(args.export)
            payload = {"robot": robot.name, "export": args.export, **notes}
            out(args, payload, lambda: f"wrote {args.export}")
            return 0
        payload = {"robot": robot.name, "url": scene.url, **notes}
        out(args, payload, lambda: f"Meshcat viewer for {robot.name}: {scene.url}\n(serving; Ctrl-C to stop)")
        sys.stdout.flush()
        try:
            if args.serve_seconds is not None:
                time.sleep(args.serve_seconds)
            else:
                while True:
                    time.sleep(0.5)
        except KeyboardInterrupt:
            pass
        return 0
    finally:
        scene.close()


def _planar(robot: Any) -> bool:
    from .errors import UnsupportedRobotError
    from .scara import ScaraParams

    try:
        ScaraParams.from_robot(robot)
    except UnsupportedRobotError:
        return False
    return True
