"""One guidance control step (force in, joint command out) against the 1 kHz budget, with the
Pinocchio calls the same step would make measured side by side in one run.

Goal: p99 <= 50 us (a twentieth of the 1 ms period).
Run: python benchmarks/bench_guidance_step.py [--steps 20000] [--generic-steps 5000] [--quick] [--json]
The JSON holds JSON_KEYS: `rows`, each timed call (ROWS) with its p50_us, p99_us and max_us
(ROW_KEYS), and the ratio of the two full steps' p99; `machine` is `_timing.calibration()`.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pinocchio as pin
from _timing import calibration, dump, machine_line, parse

from kinematics.guidance.controller import Controller, GuidanceParams, ScaraKinematics, SerialKinematics
from kinematics.mechanisms.scara.closed_form import ScaraParams
from kinematics.model.robot import load_robot

ROWS = {
    "step_closed_form": "full step, closed forms (ScaraKinematics)",
    "ellipse_closed_form": "  of which: ellipse radii + direction (closed form)",
    "ik_closed_form": "  of which: IK with limits (closed form)",
    "pinocchio_frames_fk": "Pinocchio framesForwardKinematics",
    "pinocchio_frame_jacobian": "Pinocchio computeFrameJacobian",
    "step_generic_pinocchio": "full step, generic Pinocchio path (SerialKinematics)",
}
JSON_KEYS = ("steps", "generic_steps", "rows", "ratio_p99_generic_to_closed_form", "goal_met", "machine")
ROW_KEYS = ("call", "p50_us", "p99_us", "max_us")


def timings(fn, n: int) -> np.ndarray:
    out = np.empty(n)
    clock = time.perf_counter_ns
    for i in range(n):
        t = clock()
        fn(i)
        out[i] = clock() - t
    return out / 1e3  # us


def stats(us: np.ndarray) -> dict[str, float]:
    return {"p50_us": float(np.percentile(us, 50)), "p99_us": float(np.percentile(us, 99)), "max_us": float(us.max())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=20_000, help="control steps timed (closed forms, Pinocchio calls)")
    ap.add_argument("--generic-steps", type=int, default=5_000, help="control steps timed on the generic path")
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = parse(ap, {"steps": 2_000, "generic_steps": 500})
    machine = calibration()
    n = args.steps
    robot = load_robot("scara")
    sp = ScaraParams.from_robot(robot)
    kin = ScaraKinematics(sp)
    q0 = kin.ik(np.array([0.55, 0.05]), np.array([0.0, -1.0]))
    forces = np.zeros((n, 2))
    forces[:, 0] = 6.0 * np.sin(np.linspace(0, 20, n)) ** 2  # pushing and easing off

    ctrl = Controller(kin, GuidanceParams(), q0)
    step = timings(lambda i: ctrl.step(forces[i]), n)
    ctrl = Controller(kin, GuidanceParams(), q0)
    ellipse = timings(lambda i: kin.ellipse(ctrl.q), n)
    ik = timings(lambda i: kin.ik(ctrl.x, ctrl.q), n)

    model, data = robot.model, robot.model.createData()
    fid = robot.frame_id()
    q = np.asarray(q0)
    pin_fk = timings(lambda i: pin.framesForwardKinematics(model, data, q), n)
    pin_jac = timings(lambda i: pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED), n)

    gen = SerialKinematics(robot)
    ctrl_g = Controller(gen, GuidanceParams(), q0)
    gen_forces = np.concatenate([forces, np.zeros((n, 1))], axis=1)
    step_pin = timings(lambda i: ctrl_g.step(gen_forces[i % n]), args.generic_steps)

    rows = dict(zip(ROWS, (stats(t) for t in (step, ellipse, ik, pin_fk, pin_jac, step_pin)), strict=True))
    ratio = rows["step_generic_pinocchio"]["p99_us"] / rows["step_closed_form"]["p99_us"]
    out = {"steps": n, "generic_steps": args.generic_steps, "rows": [{"call": k, **r} for k, r in rows.items()],
           "ratio_p99_generic_to_closed_form": ratio, "goal_met": rows["step_closed_form"]["p99_us"] <= 50.0,
           "machine": machine}
    if args.json:
        print(dump(out))
        return
    print(f"guidance control step, SCARA, {n:,} steps (1 kHz budget: 1000 us; goal p99 <= 50 us)")
    for key, name in ROWS.items():
        r = rows[key]
        print(f"  {name:<52} p50 {r['p50_us']:7.2f} us   p99 {r['p99_us']:7.2f} us   max {r['max_us']:8.1f} us")
    print(f"  ratio p99 generic / closed-form step: {ratio:.1f} x")
    print(f"  {machine_line(machine)}")


if __name__ == "__main__":
    main()
