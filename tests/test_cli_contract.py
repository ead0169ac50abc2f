"""The contract every command keeps (issue 11): bad input is one line on stderr and exit 2, with no
traceback and no file left behind; unreachable targets are answers (exit 1); outputs are checked
before any work; stdout closed early, a full disk and Ctrl-C end quietly."""

from __future__ import annotations

import errno
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from kinematics.cli.app import main

from .conftest import COMMANDS

MODELS = Path(__file__).parent / "models"
FOURBAR = str(MODELS / "fourbar.urdf")

# every command and every option that takes a value, with values that must be refused before
# any work: (argv, text the one error line must contain). Output paths are relative to the
# test's working directory (a fresh tmp_path); "adir" is a directory there, "nodir/" is not.
EXP = ["guide", "--experiment", "1"]
SHOW = ["show", "p2us", "--export", "v.html"]
SWEEP = ["sweep", "p2us", "--param", "b=0.3"]
URDF = ["urdf", "p2us", "-o", "d.urdf"]
NUMBER = "expected a number"
FINITE = "must be finite"
POSITIVE = "must be positive"
# What a message must say, written out from the robots' files (not from the code under test): the
# joints of urdf/scara.urdf and of example-robot-data's UR5, the eight working-mode labels of the
# parallel robots (one sign per limb) and the SCARA's two elbows.
SCARA_DOF = "scara has 2 degrees of freedom (joint1, joint2), got {} value(s)"
UR5_DOF = ("ur5 has 6 degrees of freedom (shoulder_pan_joint, shoulder_lift_joint, elbow_joint, wrist_1_joint, "
           "wrist_2_joint, wrist_3_joint), got {} value(s)")
MODES8 = "valid: +++, ++-, +-+, +--, -++, -+-, --+, ---"
ELBOWS = "valid: up, down"
# where --mode also takes `union` (usable-workspace, workspace-mesh, dexterity, synthesize), the
# refusal lists it with the modes
OR_UNION = ", union"


def unknown_mode(label: str, valid: str = MODES8) -> tuple[str, str]:
    """The needles of an unknown working mode: the label given and every valid one."""
    return f"unknown mode {label!r}", valid


# A needle is a text, or a tuple of texts, that the one error line must contain.
CASES: list[tuple[list[str], str | tuple[str, ...]]] = [
    # the command itself
    (["nosuchcommand"], "invalid choice"),
    (["--bogus"], "unrecognized arguments"),
    (["info"], "required: ROBOT"),
    (["info", "nosuchbot"], "unknown robot"),
    (["info", "nodir/x.urdf"], "no such file"),
    (["info", "adir"], "adir: a folder with no .urdf file in it"),
    (["info", "scara", "--frame", "x"], "unrecognized arguments"),
    (["info", "scara", "--range", "joint1=1:0"], ("expected JOINT=LO:HI with finite LO < HI", "got 'joint1=1:0'")),
    (["info", "scara", "--range", "nojoint=0:1"], ("unknown joint 'nojoint'", "valid: joint1, joint2")),
    (["info", "scara", "--range", "joint1=0:1e7"], "at most 1e+06 in magnitude"),  # finite, LO < HI, too large
    # workspace-volume has no --angle-step-deg: the joint-grid scan's refusal names the ranges too
    (["workspace-volume", "scara", "--range", "joint2=-1e6:1e6"], ("joint ranges of 3.84 and 2e+06 rad", "--range")),
    # the p2us's and the Delta's limits are design parameters read from the URDF, which a joint
    # range does not reach: refused, not silently ignored (an IK "within limits" outside it)
    (["ik", "delta", "--position", "0", "0", "-0.8", "--range", "actuator_1=0.5:0.6"],
     ("--range", "design parameters", "kinematics urdf delta")),
    (["workspace-volume", "p2us", "--range", "slider_1=0.1:0.2"], ("--range", "kinematics urdf p2us")),
    # fk
    (["fk", "scara"], "needs joint values"),
    (["fk", "scara", "--q"], "expected at least one argument"),
    (["fk", "scara", "--q", "0"], SCARA_DOF.format(1)),
    (["fk", "scara", "--q", "0", "0", "0"], SCARA_DOF.format(3)),
    (["fk", "scara", "--q", "zero", "0"], NUMBER),
    (["fk", "scara", "--q", "nan", "0"], FINITE),
    (["fk", "scara", "--q", "inf", "0"], FINITE),
    (["fk", "scara", "--q", "1e308", "0"], FINITE),
    (["fk", "scara", "--q", "0", "-10000000"], FINITE),
    (["fk", "scara", "--q", "0", "-1e7"], FINITE),  # an exponent is a number, not an option
    (["fk", "scara", "--q", "-inf", "0"], FINITE),
    (["fk", "scara", "--q", "0", "0", "--frame", "nope"], "unknown frame"),
    (["fk", "scara", "--q", "0", "0", "--frame"], "expected one argument"),
    (["fk", "nosuchbot", "--q", "0"], "unknown robot"),
    (["fk", "p2us", "--q", "0.3", "0.2"], "3 actuated joints"),
    (["fk", "p2us", "--q", "0.3", "0.2", "0.2", "0.2"], "3 actuated joints"),
    (["fk", "p2us", "--q", "0.3", "nan", "0.2"], FINITE),
    (["fk", "p2us", "--q", "1e308", "0.2", "0.2"], FINITE),
    (["fk", FOURBAR, "--q", "0.1", "0.2"], "actuated"),
    (["fk", "ur5", "--q", "0", "0"], UR5_DOF.format(2)),
    # ik
    (["ik", "scara"], "required: --position"),
    (["ik", "scara", "--position", "0.1"], "give X Y"),
    (["ik", "scara", "--position", "0.1", "0.2", "0.3"], "give X Y"),
    (["ik", "scara", "--position", "0.1", "nan"], FINITE),
    (["ik", "scara", "--position", "0.1", "1e999"], FINITE),
    (["ik", "scara", "--position", "1e308", "1e308"], FINITE),
    (["ik", "scara", "--position", "x", "0"], NUMBER),
    (["ik", "p2us", "--position", "0", "-0.4"], "X Y Z"),
    (["ik", "p2us", "--position", "1e308", "1e308", "1e308"], FINITE),
    (["ik", "p2us", "--position", "0", "0", "nan"], FINITE),
    (["ik", "ur5", "--position", "0.1", "0.2", "0.3"], "for closed loops by the batched solver; this one is neither"),
    (["ik", "nodir/x.urdf", "--position", "0", "0"], "no such file"),
    # jacobian
    (["jacobian", "scara"], "needs joint values"),
    (["jacobian", "scara", "--q", "0"], SCARA_DOF.format(1)),
    (["jacobian", "scara", "--q", "0", "nan"], FINITE),
    (["jacobian", "scara", "--q", "0", "0", "--task", "bogus"], "invalid choice"),
    (["jacobian", "scara", "--q", "0", "0", "--frame", "nope"], "unknown frame"),
    (["jacobian", "ur5", "--q", "0", "0", "0"], UR5_DOF.format(3)),
    # --position and --mode pose the p2us and the Delta: a serial arm's are refused, not ignored
    (["jacobian", "ur5", "--q", "0", "0", "0", "0", "0", "0", "--position", "0", "0", "0"], ("--position", "--q")),
    (["jacobian", "ur5", "--q", "0", "0", "0", "0", "0", "0", "--mode", "+++"], ("--mode", "serial")),
    (["mobility", "ur5", "--q", "0", "0", "0", "0", "0", "0", "--mode", "+++"], ("--mode", "serial")),
    (["jacobian", "ur5", "--q", "0", "0", "0", "0", "0", "0", "--task", "planar"],
     ("not a planar arm", "auto, translation, rotation or full")),  # every task that would work
    (["jacobian", "p2us"], "X Y Z"),
    (["jacobian", "p2us", "--position", "0", "0"], "expected 3 arguments"),
    (["jacobian", "p2us", "--position", "0", "0", "nan"], FINITE),
    (["jacobian", "p2us", "--position", "0", "0", "1e308"], FINITE),
    (["jacobian", "p2us", "--position", "0", "0", "-0.45", "--mode", "zzz"], unknown_mode("zzz")),
    (["jacobian", "p2us", "--position", "0", "0", "-0.45", "--mode", "++"], unknown_mode("++")),
    (["jacobian", "p2us", "--q", "0.3", "0.3", "0.3"], "--position"),
    # the closed forms give the platform's translational J only: another frame or task is refused (as
    # fk refuses the frame), not answered with the platform's J
    (["jacobian", "p2us", "--position", "0", "0", "-0.45", "--frame", "base"], ("--frame", "frame 'platform'")),
    (["jacobian", "delta", "--position", "0", "0", "-0.8", "--task", "rotation"], ("--task", "auto or translation")),
    (["jacobian", FOURBAR, "--q", "0.1", "0.2"], "actuated"),
    # manipulability
    (["manipulability", "scara"], "required: --q"),
    (["manipulability", "scara", "--q", "0"], SCARA_DOF.format(1)),
    (["manipulability", "scara", "--q", "0", "inf"], FINITE),
    (["manipulability", "scara", "--q", "0", "0", "--frame", "nope"], "unknown frame"),
    (["manipulability", "p2us", "--q", *["0"] * 18], "serial robot"),
    (["manipulability", "nosuchbot", "--q", "0"], "unknown robot"),
    # mobility
    (["mobility", "nosuchbot"], "unknown robot"),
    (["mobility", "scara", "--q", "0"], SCARA_DOF.format(1)),
    (["mobility", "scara", "--q", "0", "nan"], FINITE),
    (["mobility", "scara", "--position", "0", "0", "0"], "serial"),
    (["mobility", "p2us", "--q", "0.3"], "3 actuated"),
    (["mobility", "p2us", "--q", "0.3", "0.3", "1e308"], FINITE),
    (["mobility", "p2us", "--position", "0", "0", "nan"], FINITE),
    (["mobility", "p2us", "--position", "1e308", "1e308", "1e308"], FINITE),
    (["mobility", "p2us", "--position", "0", "0", "-0.45", "--q", "0.2", "0.2", "0.2"], "not both"),
    (["mobility", "p2us", "--position", "0", "0", "-0.45", "--mode", "zzz"], unknown_mode("zzz")),
    (["mobility", "p2us", "--position", "10", "10", "10", "--mode", "zzz"], unknown_mode("zzz")),
    # an empty --mode is a label to refuse, not the default mode (likewise below)
    (["mobility", "p2us", "--position", "0", "0", "-0.45", "--mode", ""], unknown_mode("")),
    # workspace-volume
    (["workspace-volume", "nosuchbot"], "unknown robot"),
    (["workspace-volume", str(MODELS / "rssr.urdf")], "1-dimensional"),
    (["workspace-volume", "delta", "--modes", "+0+"], unknown_mode("+0+")),
    (["workspace-volume", "delta", "--limits", "strokes"], "invalid choice"),
    (["workspace-volume", "scara", "--obstacles", "nofile.yaml"], "nofile.yaml: obstacle file not found"),
    (["singularities", "ur5", "--max-points", "10"], "at least 1000"),
    (["singularities", "ur5", "--max-points", "0.5"], "must be at least 1000, got 0.5"),  # not "at least 1"
    (["singularities", "ur5", "--max-points", "1e12"], "over the 200,000,000 limit"),
    (["singularities", "ur5", "--max-points", "nan"], POSITIVE),
    (["singularities", "ur5", "--resolution", "2"], "at least 4"),
    (["singularities", "ur5", "--resolution", "1e9"], "expected a whole number"),
    (["singularities", "ur5", "--resolution", "100000000"], "over the 200,000,000 limit"),
    (["singularities", "ur5", "--modes", "up"], "working modes"),
    (["singularities", "ur5", "--limits", "actuators"], "URDF's joint limits"),
    (["singularities", "ur5", "--plot", "w.png"], "no figure"),
    (["singularities", "ur5", "--obstacles", "nofile.yaml"], "nofile.yaml: obstacle file not found"),
    (["singularities", "ur5", "--collisions", "--base-step-deg", "0"], "must be in (0, 90] degrees"),
    (["singularities", "ur5", "--collisions", "--base-step-deg", "90.01"], "must be in (0, 90] degrees"),
    (["singularities", "ur5", "--collisions", "--base-step-deg", "nan"], "must be in (0, 90] degrees"),
    (["singularities", "ur5", "--collisions", "--base-step-deg", "deg"], "expected a number of degrees"),
    (["singularities", "ur5", "--base-step-deg", "5"], "--base-step-deg: is for serial arms with --collisions"),
    (["workspace-volume", "ur5", "--collisions", "--turn", "sideways"], "invalid choice: 'sideways'"),
    (["workspace-volume", "ur5", "--turn", "spatial"], "--turn: is for a serial arm's volume with --collisions"),
    (["singularities", "scara", "--collisions", "--base-step-deg", "5"], "is for serial arms"),
    (["workspace-volume", "ur5", "--collisions", "--plot", "w.png"], "over the 200,000 limit"),  # before the volume
    (["show", "ur5", "--workspace", "--collisions", "--step", "0.005", "--export", "x.html"], "too fine a step"),
    (["show", "ur5", "--workspace", "--collisions", "--limits", "actuators", "--export", "x.html"], "joint limits only"),
    # a serial arm has no working mode: said, not "valid: " with an empty list
    (["workspace-volume", "ur5", "--modes", "up"], "unknown mode 'up'; valid: none (ur5 has no mode to choose)"),
    (["workspace-volume", "ur5", "--limits", "actuators"], "actuators"),
    (["workspace-volume", "ur5", "--tool-axis", "0", "0", "0"], "not all zero"),
    (["workspace-volume", "ur5", "--tool-axis", "0", "0", "x"], NUMBER),
    (["workspace-volume", "p2us", "--tool-axis", "0", "0", "-1"], "keeps one orientation"),
    (["workspace-volume", "p2us", "--tool-frame", "base"], "closed forms compute the position of its platform"),
    (["info", "ur5", "--tool-frame", "nosuch"], "unknown frame 'nosuch'"),
    (["workspace-volume", "ur5", "--orientation", "rpy 1 2"], "rpy R P Y"),
    (["workspace-volume", "ur5", "--orientation", "rpy 0 0 0", "--tool-axis", "0", "0", "1"], "not allowed with"),
    (["workspace-volume", "ur5", "--tool-axis", "0", "0", "0", "--collisions"], "not all zero"),
    (["workspace-volume", "ur5", "--orientation", "rpy 0 0", "--obstacles", "cell.yaml"], "rpy"),
    (["workspace-volume", "scara", "--points", "adir"], "is a directory"),
    (["workspace-volume", "p2us", "--step", "0"], POSITIVE),
    (["workspace-volume", "p2us", "--step", "-0.01"], POSITIVE),
    (["workspace-volume", "p2us", "--step", "nan"], POSITIVE),
    (["workspace-volume", "p2us", "--step", "inf"], POSITIVE),
    (["workspace-volume", "p2us", "--step", "x"], NUMBER),
    (["workspace-volume", "p2us", "--step", "1e-9"], "over the 200,000,000 limit"),
    (["workspace-volume", "scara", "--step", "1e-7"], "over the 200,000,000 limit"),
    (["workspace-volume", "p2us", "--modes", "zzz"], unknown_mode("zzz")),
    (["workspace-volume", "p2us", "--modes", "+++", "up"], unknown_mode("up")),
    (["workspace-volume", "scara", "--modes", "zzz"], unknown_mode("zzz", ELBOWS)),
    (["workspace-volume", "p2us", "--limits", "some"], "invalid choice"),
    (["workspace-volume", "p2us", "--rtol", "-1"], "must be 0 or positive"),  # 0 is allowed: the message says so
    (["workspace-volume", "p2us", "--rtol", "nan"], "must be 0 or positive and finite"),
    (["workspace-volume", "p2us", "--rtol", "x"], NUMBER),
    (["workspace-volume", "scara", "--rtol", "1e-12"], "too tight a tolerance"),  # refused after the first grid
    (["workspace-volume", "p2us", "--plot", "myplot"], "unknown suffix"),
    (["workspace-volume", "p2us", "--plot", "plot.foo"], "unknown suffix"),
    (["workspace-volume", "p2us", "--plot", "adir"], "is a directory"),
    (["workspace-volume", "p2us", "--plot", "nodir/p.png"], "does not exist"),
    (["workspace-volume", "p2us", "--plot", ""], "is a directory"),
    (["workspace-volume", "p2us", "--points", "pts.xyz"], "unknown suffix"),
    (["workspace-volume", "p2us", "--points", "adir"], "is a directory"),
    (["workspace-volume", "p2us", "--points", "nodir/p.npy"], "does not exist"),
    (["workspace-volume", "p2us", "--points", "adir/"], "is a directory"),
    # singularities
    (["singularities", "nosuchbot"], "unknown robot"),
    (["singularities", str(MODELS / "rssr.urdf")], "scanned over a 2D or 3D grid; this task space is 1-dimensional"),
    (["usable-workspace", "ur5", "--shape", "cube"], "needs its mechanism's ik"),
    (["singularities", "delta", "--paper-scan"], "3-[P2(US)]"),
    (["singularities", "ur5", "--max-points", "0"], POSITIVE),
    (["singularities", "ur5", "--modes", "+++"], "working modes"),
    (["singularities", "p2us", "--step", "0"], POSITIVE),
    (["singularities", "p2us", "--step", "1e-9"], "over the 200,000,000 limit"),
    (["singularities", "p2us", "--modes", "zzz"], unknown_mode("zzz")),
    (["singularities", "p2us", "--limits", "x"], "invalid choice"),
    (["singularities", "p2us", "--plot", "s.foo"], "unknown suffix"),
    (["singularities", "p2us", "--plot", "adir"], "is a directory"),
    (["singularities", "p2us", "--plot", "nodir/s.png"], "does not exist"),
    (["singularities", "scara", "--angle-step-deg", "1e-9"], "over the 200,000,000 limit"),
    (["singularities", "delta", "--angle-step-deg", "5"], ("--angle-step-deg", "planar arm")),  # not ignored
    # a serial arm's cell-engine flags where no cell engine runs: refused, not ignored
    (["singularities", "p2us", "--max-points", "5000"], ("--max-points", "serial arm's joint boxes")),
    (["singularities", FOURBAR, "--resolution", "10"], ("--resolution", "task-space points")),
    (SHOW + ["--workspace", "--max-points", "5000"], ("--max-points", "show runs it only")),
    (["show", "scara", "--workspace", "--resolution", "10", "--export", "v.html"], ("--resolution", "serial arm")),
    (["show", "ur5", "--max-points", "5000", "--export", "v.html"], ("--max-points", "--singularities")),
    (["singularities", "scara", "--angle-step-deg", "0"], POSITIVE),
    (["singularities", "scara", "--angle-step-deg", "-1"], POSITIVE),
    (["singularities", "scara", "--angle-step-deg", "nan"], POSITIVE),
    (["singularities", "scara", "--angle-step-deg", "deg"], NUMBER),
    (["singularities", "scara", "--plot", "s"], "unknown suffix"),
    (["singularities", "scara", "--modes", "zzz"], unknown_mode("zzz", ELBOWS)),
    # sweep
    (["sweep", "p2us"], "give at least one"),
    (["sweep", "scara", "--param", "b=0.3"], "3-[P2(US)]"),
    (["sweep", "p2us", "--param", "b"], "NAME=START:STOP:COUNT"),
    (["sweep", "p2us", "--param", "zz=1:2:3"], "unknown parameter"),
    (["sweep", "p2us", "--param", "b=0.3:0.4"], "START:STOP:COUNT"),
    (["sweep", "p2us", "--param", "b=0.3:0.4:0"], "COUNT >= 1"),
    (["sweep", "p2us", "--param", "b=0.3:0.4:x"], "START:STOP:COUNT"),
    (["sweep", "p2us", "--param", "b=nan:0.4:2"], "finite"),
    (["sweep", "p2us", "--param", "b=0.3", "--param", "b=0.4"], "twice"),
    (["sweep", "p2us", "--param", "b=0.3:0.4:100000000"], "over the 200,000,000 limit"),
    (["sweep", "p2us", "--param", "b=0.3:0.4:1000", "--param", "d=0.02:0.03:1000"], "over the 200,000,000 limit"),
    (["sweep", "p2us", "--param", "L=-1"], "L: must be a positive length [m], got -1.0"),
    (["synthesize", "p2us", "--obstacles", "nofile.yaml"], "nofile.yaml: obstacle file not found"),
    ([*SWEEP, "--obstacles", "nofile.yaml"], "nofile.yaml: obstacle file not found"),
    ([*SWEEP, "--workers", "-1"], "at least 1"),
    ([*SWEEP, "--workers", "0"], "at least 1"),
    ([*SWEEP, "--workers", "100000"], "limit"),
    ([*SWEEP, "--workers", "two"], "whole number"),
    ([*SWEEP, "--step", "0"], POSITIVE),
    ([*SWEEP, "--step", "1e-9"], "over the 200,000,000 limit"),
    ([*SWEEP, "--rtol", "0"], POSITIVE),
    ([*SWEEP, "--rtol", "-0.001"], POSITIVE),
    ([*SWEEP, "--out", "adir"], "is a directory"),
    ([*SWEEP, "--out", "table.txt"], "unknown suffix"),
    ([*SWEEP, "--out", "nodir/t.csv"], "does not exist"),
    ([*SWEEP, "--scheduler", "notascheme://x"], "--scheduler: cannot reach 'notascheme://x'"),
    # guide
    (["guide"], "required: --experiment"),
    (["guide", "--experiment", "4"], "invalid choice"),
    (["guide", "--experiment", "one"], "invalid int"),
    ([*EXP, "--robot", "p2us"], "planar 2R arm"),
    ([*EXP, "--robot", "nosuchbot"], "unknown robot"),
    ([*EXP, "--robot", "ur5"], "ur5: a planar 2R arm needs two revolute joints"),
    ([*EXP, "--force", "nan"], FINITE),
    ([*EXP, "--force", "1e308"], FINITE),
    ([*EXP, "--mass", "0"], POSITIVE),
    ([*EXP, "--mass", "-5"], POSITIVE),
    ([*EXP, "--damping", "0"], POSITIVE),
    ([*EXP, "--damping", "inf"], POSITIVE),
    ([*EXP, "--v-max", "0"], POSITIVE),
    ([*EXP, "--saturation", "both"], "invalid choice"),
    ([*EXP, "--threshold", "-0.1"], POSITIVE),
    ([*EXP, "--k-max", "nan"], POSITIVE),
    ([*EXP, "--gain", "0"], POSITIVE),
    ([*EXP, "--dt", "0"], POSITIVE),
    ([*EXP, "--dt", "1e308"], "at least 1 is needed"),
    ([*EXP, "--dt", "1e-12"], "over the 2,000,000 limit"),
    ([*EXP, "--dt", "x"], NUMBER),
    ([*EXP, "--dt", "0.01", "--mass", "1e-300"], "out of a computable range"),
    ([*EXP, "--dt", "0.01", "--k-max", "1e300"], "out of a computable range"),
    ([*EXP, "--plot", "g"], "unknown suffix"),
    ([*EXP, "--plot", "adir"], "is a directory"),
    ([*EXP, "--plot", "nodir/g.png"], "does not exist"),
    ([*EXP, "--csv", "g.json"], "unknown suffix"),
    ([*EXP, "--csv", "adir"], "is a directory"),
    ([*EXP, "--csv", "nodir/g.csv"], "does not exist"),
    # show (always with --export: no viewer is started)
    (["show", "nosuchbot", "--export", "v.html"], "unknown robot"),
    ([*SHOW, "--q", "0.3", "0.3"], "p2us has 3 actuated joints (slider_1, slider_2, slider_3), got 2"),
    ([*SHOW, "--q", "0.3", "0.3", "nan"], FINITE),
    ([*SHOW, "--position", "0", "0", "nan"], FINITE),
    ([*SHOW, "--position", "1e308", "1e308", "1e308"], FINITE),
    ([*SHOW, "--position", "0", "0"], "expected 3 arguments"),
    ([*SHOW, "--mode", "zzz", "--position", "0", "0", "-0.45"], unknown_mode("zzz")),
    ([*SHOW, "--guide", "4"], "invalid choice"),
    ([*SHOW, "--guide", "1"], "planar arms"),
    ([*SHOW, "--limits", "x"], "invalid choice"),
    ([*SHOW, "--step", "0"], POSITIVE),
    ([*SHOW, "--step", "1e-9", "--workspace"], "limit"),
    ([*SHOW, "--step", "0.001", "--singularities"], "limit"),
    ([*SHOW, "--serve-seconds", "-1"], "must be 0 or positive"),
    (["show", "p2us", "--export", "v.png"], "unknown suffix"),
    (["show", "p2us", "--export", "adir"], "is a directory"),
    (["show", "p2us", "--export", "nodir/v.html"], "does not exist"),
    (["show", "scara", "--export", "v.html", "--position", "0", "0", "0"], "--position: poses the p2us and the Delta; give scara's joint values"),
    # --mode poses the p2us and the Delta at --position: elsewhere it was ignored (exit 0)
    (["show", "ur5", "--export", "v.html", "--mode", "+++"], "--mode: poses the p2us and the Delta; give ur5's joint values"),
    (["show", "p2us", "--export", "v.html", "--mode", "+++"], "--mode: the working mode of --position"),
    (["show", FOURBAR, "--export", "v.html", "--position", "0", "0", "0"], "give fourbar's actuator values with --q"),
    (["show", "delta", "--export", "v.html", "--mode", "+++", "--q", "0", "0", "0"], "--mode: the working mode of --position"),
    # --q's actuators won over --position, which was ignored (exit 0)
    (["show", "p2us", "--export", "v.html", "--position", "0", "0", "-0.45", "--q", "0.1", "0.1", "0.1"],
     "--position/--q: give one of them, not both"),
    (["show", "scara", "--export", "v.html", "--q", "0"], SCARA_DOF.format(1)),
    (["show", "ur5", "--export", "v.html", "--workspace", "--max-points", "1e12"], "over the 200,000,000 limit"),
    (["show", "ur5", "--export", "v.html", "--workspace", "--resolution", "x"], "expected a whole number"),
    (["show", "ur5", "--export", "v.html", "--guide", "1"], "planar arms"),
    # the double pendulum is a planar arm, but not of the scara family the guidance runs on
    (["show", "double_pendulum", "--export", "v.html", "--guide", "1"], ("planar 2R arms", "scara family", "which double_pendulum is not")),
    (["show", "scara", "--export", "v.html", "--mesh", "nofile.stl"], "no such file"),
    (["show", "scara", "--export", "v.html", "--mesh", "m.obj"], "unknown suffix"),
    (["show", "delta", "--export", "v.html", "--position", "0", "0", "0.5", "--mode", "+0+"], unknown_mode("+0+")),
    (["show", "delta", "--export", "v.html", "--position", "0", "0", "-0.8", "--mode", ""], unknown_mode("")),
    # urdf
    (["urdf", "p2us"], "required: -o/--output"),
    (["urdf", "scara", "-o", "d.urdf"], "invalid choice"),
    (["urdf", "p2us", "-o", "adir"], "is a directory"),
    (["urdf", "p2us", "-o", "d.txt"], "unknown suffix"),
    (["urdf", "p2us", "-o", "nodir/d.urdf"], "does not exist"),
    ([*URDF, "--b", "nan"], FINITE),
    ([*URDF, "--b", "-1"], "b: must be a positive length [m], got -1.0"),
    ([*URDF, "--d", "0"], "d: must be a positive length [m], got 0.0"),
    ([*URDF, "--L", "-1"], "positive length"),
    ([*URDF, "--L", "1e308"], FINITE),
    ([*URDF, "--beta", "x"], NUMBER),
    ([*URDF, "--alpha", "0", "120"], "expected 3 arguments"),
    ([*URDF, "--stroke", "0.6", "0.1"], ("stroke: need finite lower < upper", "got (0.6, 0.1)")),
    ([*URDF, "--stroke", "0.1"], "expected 2 arguments"),
    ([*URDF, "--theta", "nan", "1"], FINITE),
    ([*URDF, "--phi", "1", "-1"], ("phi_limits: need finite lower < upper", "got (1.0, -1.0)")),
    ([*URDF, "--theta-zero", "inf"], FINITE),
    ([*URDF, "--rod-spacing", "-0.05"], "rod_spacing: must be a positive length [m], got -0.05"),
    ([*URDF, "--rod-radius", "-1"], "--rod-radius: must be positive and finite, got -1"),
    ([*URDF, "--arm-radius", "nan"], "--arm-radius: must be positive and finite, got nan"),
    ([*URDF, "--plate-thickness", "0"], "--plate-thickness: must be positive and finite, got 0"),
    ([*URDF, "--plate-overhang", "x"], "--plate-overhang"),
    ([*URDF, "--platform-overhang", "inf"], "--platform-overhang: must be positive and finite"),
    (["urdf", "delta", "-o", "d.urdf", "--forearm", "-1"], "lb: must be a positive length [m], got -1.0"),
    (["urdf", "delta", "-o", "d.urdf", "--upper-arm", "-1"], "la: must be a positive length [m], got -1.0"),
    (["urdf", "delta", "-o", "d.urdf", "--cone", "95", "--degrees"], ("cone half-angle must be within (0, 90) degrees",
                                                                      "got 95.0")),
    (["urdf", "delta", "-o", "d.urdf", "--elbow-socket", "200", "--degrees"], ("within (-180, 180] degrees", "got 200.0")),
    (["urdf", "delta", "-o", "d.urdf", "--platform-socket", "90", "--degrees"], ("within [0, 90) degrees", "got 90.0")),
    (["urdf", "delta", "-o", "d.urdf", "--L", "0.3"], "p2us only"),
    (["urdf", "delta", "-o", "d.urdf", "--design", "results"], "p2us only"),
    # usable-workspace and workspace-mesh
    (["usable-workspace", "p2us"], "required: --shape"),
    (["usable-workspace", "p2us", "--shape", "cone"], "invalid choice"),
    (["usable-workspace", "p2us", "--shape", "cube", "--kappa-max", "0.5"], ">= 1"),
    (["usable-workspace", "p2us", "--shape", "cube", "--kappa-max", "nan"], POSITIVE),
    (["usable-workspace", "p2us", "--shape", "cube", "--mode", "zzz"], unknown_mode("zzz", MODES8 + OR_UNION)),
    (["usable-workspace", "p2us", "--shape", "cube", "--mode", ""], unknown_mode("", MODES8 + OR_UNION)),
    (["usable-workspace", "p2us", "--shape", "cube", "--step", "0"], POSITIVE),
    (["usable-workspace", "p2us", "--shape", "cube", "--step", "1e-9"], "200,000,000"),
    (["usable-workspace", "scara", "--shape", "cube"], "a cube needs a 3-D task space"),
    (["usable-workspace", "p2us", "--shape", "cube", "--obstacles", "nofile.yaml"], "obstacle file not found"),
    (["usable-workspace", "delta", "--shape", "cube", "--limits", "some"], "invalid choice"),
    (["workspace-mesh", "p2us"], "required: -o"),
    (["workspace-mesh", "p2us", "-o", "m.obj"], "unknown suffix"),
    (["workspace-mesh", "p2us", "-o", "nodir/m.stl"], "does not exist"),
    (["workspace-mesh", "p2us", "-o", "m.stl", "--step", "-1"], POSITIVE),
    (["workspace-mesh", "p2us", "-o", "m.stl", "--step", "1e-9"], "200,000,000"),
    (["workspace-mesh", "p2us", "-o", "m.stl", "--mode", "zzz"], unknown_mode("zzz", MODES8 + OR_UNION)),
    (["workspace-mesh", "p2us", "-o", "m.stl", "--mode", ""], unknown_mode("", MODES8 + OR_UNION)),
    (["workspace-mesh", "p2us", "-o", "m.stl", "--limits", "none"], "invalid choice"),
    # dexterity
    (["dexterity", "nosuchbot"], "unknown robot"),
    (["dexterity", "scara", "--mode", "zzz"], unknown_mode("zzz", ELBOWS + OR_UNION)),
    (["dexterity", "delta", "--mode", "up"], unknown_mode("up", MODES8 + OR_UNION)),
    (["dexterity", "scara", "--samples", "0"], "at least 16"),
    (["dexterity", "scara", "--samples", "1e6"], "expected a whole number"),
    (["dexterity", "scara", "--samples", "100000000000"], "at most"),
    (["dexterity", "scara", "--replicates", "1"], "need at least 2 independent replicates for an error bar, got 1"),
    (["dexterity", "scara", "--seed", "x"], "expected a whole number"),
    (["dexterity", "scara", "--limits", "actuators"], ("unknown choice 'actuators'", "valid: all")),
    (["dexterity", "scara", "--step", "0"], POSITIVE),
    (["dexterity", "scara", "--cells", "0"], "positive number of cells"),
    (["dexterity", "scara", "--cells-out", "c.csv"], "needs --cells"),
    (["dexterity", "scara", "--cells", "4", "--cells-out", "adir"], "is a directory"),
    (["dexterity", "scara", "--cells", "4", "--cells-out", "c.txt"], "unknown suffix"),
    (["dexterity", "scara", "--plot", "k.foo"], "unknown suffix"),
    (["dexterity", "scara", "--export", "k.png"], "unknown suffix"),
    (["dexterity", "scara", "--export", "nodir/k.html"], "does not exist"),
    (["dexterity", "ur5", "--mode", "up"], "unknown mode 'up'"),
    # synthesize
    (["synthesize", "p2us"], "give at least one"),
    (["synthesize", "delta"], "e.g. R=0.16:0.24; variables: R, r"),  # the delta's own (R = 0.2 m), not the p2us' b
    (["synthesize", "scara", "--param", "b=0.3:0.4"], "3-[P2(US)]"),
    (["synthesize", "p2us", "--param", "zz=1:2"], "unknown parameter"),
    (["synthesize", "delta", "--param", "b=0.3:0.4"], "unknown parameter"),
    (["synthesize", "p2us", "--param", "b=0.3"], "LOWER:UPPER"),
    (["synthesize", "p2us", "--param", "b=0.4:0.3"], "LOWER < UPPER"),
    (["synthesize", "p2us", "--param", "b=nan:0.3"], "finite"),
    (["synthesize", "p2us", "--param", "b=0.3:0.4", "--param", "b=0.3:0.5"], "twice"),
    (["synthesize", "p2us", "--param", "b=0.3:0.4", "--population", "2"], ">= 4"),
    (["synthesize", "p2us", "--param", "b=0.3:0.4", "--generations", "0"], "generations >= 1"),
    (["synthesize", "p2us", "--param", "b=0.3:0.4", "--population", "100000"], "limit"),
    (["synthesize", "p2us", "--param", "b=0.3:0.4", "--mode", "zzz"], unknown_mode("zzz", MODES8 + OR_UNION)),
    (["synthesize", "p2us", "--param", "b=0.3:0.4", "--mode", ""], unknown_mode("", MODES8 + OR_UNION)),
    (["synthesize", "p2us", "--param", "b=0.3:0.4", "--kappa-max", "0.5"], ">= 1"),
    (["synthesize", "p2us", "--param", "b=0.3:0.4", "--cube-cells", "1"], "cube_cells"),
    (["synthesize", "p2us", "--param", "b=0.3:0.4", "--gci-samples", "4"], "at least 16"),
    (["synthesize", "p2us", "--param", "b=0.3:0.4", "--workers", "1000"], "at most 4 per core"),
    (["synthesize", "p2us", "--param", "b=0.3:0.4", "--out", "f.txt"], "unknown suffix"),
    (["synthesize", "p2us", "--param", "b=0.3:0.4", "--plot", "nodir/f.png"], "does not exist"),
    # fk over a file of configurations
    (["fk", "ur5", "--q-file", "nofile.csv", "--out", "p.csv"], "no such file"),
    (["fk", "ur5", "--q-file", "q.csv"], "needs --out"),
    (["fk", "ur5", "--q-file", "q.csv", "--out", "p.txt"], "unknown suffix"),
]


@pytest.fixture()
def workdir(tmp_path, monkeypatch):
    (tmp_path / "adir").mkdir()
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _listing(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


def _options_with_values(capsys, command: str) -> set[str]:
    """The options of `kinematics COMMAND --help`'s usage that take a value (`--opt METAVAR`)."""
    assert main([command, "--help"]) == 0
    usage = capsys.readouterr().out.split("\n\n")[0]
    return set(re.findall(r"(?<![\w-])(--?[a-z][\w-]*) [A-Z{]", usage))


def test_every_command_and_every_option_with_a_value_has_a_case(capsys):
    """The table covers what its comment says: every command, and every option that takes a value
    (an option shared by several commands, such as --range, at least once), with no case twice."""
    assert len({tuple(a) for a, _ in CASES}) == len(CASES)
    for command in COMMANDS:
        argvs = [a for a, _ in CASES if a[0] == command]
        assert argvs, f"no case for {command}"
    given = {arg for a, _ in CASES for arg in a}
    missing = {(c, o) for c in COMMANDS for o in _options_with_values(capsys, c) if o not in given}
    assert not missing, sorted(missing)


@pytest.mark.parametrize(("argv", "needle"), CASES, ids=[" ".join(a)[:60] for a, _ in CASES])
def test_bad_input(argv, needle, capsys, workdir):
    before = _listing(workdir)
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 2, (argv, out, err)
    assert err.count("\n") == 1 and err.endswith("\n"), err  # exactly one line
    for text in (needle,) if isinstance(needle, str) else needle:
        assert text in err, (text, err)
    assert "Traceback" not in err and "Warning" not in err
    assert out == ""
    assert _listing(workdir) == before  # nothing written, nothing left behind


# -- answers, not errors: unreachable targets exit 1 in every command -------------------------------
UNREACHABLE = [
    ["ik", "scara", "--position", "0", "0.05"],
    ["ik", "p2us", "--position", "10", "10", "10"],
    ["fk", "p2us", "--q", "2", "0.1", "0.1"],
    ["jacobian", "p2us", "--position", "10", "10", "10"],
    ["mobility", "p2us", "--position", "10", "10", "10"],
    ["mobility", "p2us", "--q", "2", "0.1", "0.1"],
    ["mobility", "delta", "--position", "10", "10", "10"],
    ["mobility", "delta", "--q", "3", "0", "0"],
    ["show", "p2us", "--position", "10", "10", "10", "--export", "v.html"],
    ["show", "p2us", "--q", "2", "0.1", "0.1", "--export", "v.html"],
]


@pytest.mark.parametrize("argv", UNREACHABLE, ids=[" ".join(a[:3]) for a in UNREACHABLE])
def test_unreachable_is_exit_1(argv, capsys, workdir):
    before = _listing(workdir)
    assert main(argv) == 1
    out, err = capsys.readouterr()
    assert err == "" and ("NOT reachable" in out or "no assembly" in out), out
    assert main([*argv, "--json"]) == 1
    out, err = capsys.readouterr()
    assert '"reachable": false' in out or '"exists": false' in out
    assert _listing(workdir) == before


def test_no_arguments_lists_the_commands(capsys):
    assert main([]) == 0
    out, err = capsys.readouterr()
    assert err == "" and "workspace-volume" in out and "sweep" in out and "guide" in out


def test_help_texts_match_behaviour(capsys):
    """jacobian --mode's default and --q on closed-loop robots say what the code does."""
    assert main(["jacobian", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "default: every mode" not in text and "first mode within the limits" in text
    assert "p2us, delta: not used, give --position" in text
    code = main(["jacobian", "p2us", "--position", "0", "0", "-0.45", "--json"])
    import json

    assert code == 0 and json.loads(capsys.readouterr().out)["within_limits"] is True  # the first valid mode


def test_info_counts_coordinates_and_mobility(capsys):
    assert main(["info", "p2us"]) == 0
    out = capsys.readouterr().out
    assert "18 joint coordinates, mobility 3" in out and "degrees of freedom" not in out
    assert main(["info", "scara"]) == 0
    assert "2 degrees of freedom" in capsys.readouterr().out


def test_outputs_written_atomically(capsys, workdir):
    """A figure and a CSV land under their names, with no temporary file beside them."""
    assert main(["guide", "--experiment", "1", "--dt", "0.01", "--csv", "g.csv", "--plot", "g.png"]) == 0
    capsys.readouterr()
    assert _listing(workdir) == {"adir", "g.csv", "g.png"}
    assert (workdir / "g.png").read_bytes()[:4] == b"\x89PNG"
    assert (workdir / "g.csv").read_text().count("\n") == 601  # header + 6 s at 10 ms


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc")
def test_output_directory_that_takes_no_file_is_refused_before_work(capsys, monkeypatch):
    # /proc passes os.access(W_OK) for root, yet no file can be created in it: the check tries,
    # so the refusal comes before the volume is measured (its wording), not at the final write
    # after the work ("cannot write ...")
    import kinematics.cli.workspace as ws

    def no_work(*a, **k):
        raise AssertionError("the volume was measured before the output was refused")

    monkeypatch.setattr(ws, "workspace_volume", no_work)
    assert main(["workspace-volume", "scara", "--plot", "/proc/kinematics-test.png"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--plot" in err and "cannot create a file in directory '/proc'" in err


def test_write_atomic_leaves_nothing_on_failure(tmp_path):
    from kinematics.errors import InvalidInputError
    from kinematics.files import write_atomic

    target = tmp_path / "t.csv"
    target.write_text("old")

    def broken(path: str) -> None:
        Path(path).write_text("half")
        raise RuntimeError("writer failed")

    def interrupted(path: str) -> None:
        Path(path).write_text("half")
        raise KeyboardInterrupt

    with pytest.raises(RuntimeError):
        write_atomic(str(target), broken, "--out")
    with pytest.raises(KeyboardInterrupt):
        write_atomic(str(target), interrupted, "--out")
    (tmp_path / "sub").mkdir()
    with pytest.raises(InvalidInputError, match="--out: cannot write"):  # a directory in the way
        write_atomic(str(tmp_path / "sub"), "x", "--out")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sub", "t.csv"]
    assert target.read_text() == "old"  # the old file is untouched until a new one is complete
    write_atomic(str(target), b"new", "--out")
    assert target.read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["sub", "t.csv"]


class _FullDisk:
    """A file being written that the disk fills up under: half of the first write lands, then
    ENOSPC."""

    def __init__(self, f) -> None:
        self._f = f

    def write(self, data):
        self._f.write(data[: len(data) // 2])
        self._f.flush()
        raise OSError(errno.ENOSPC, "No space left on device")

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> bool:
        self._f.close()
        return False

    def __getattr__(self, name):
        return getattr(self._f, name)


def _disk_fills_while_writing(monkeypatch, which: str) -> None:
    """Every file opened for writing whose name contains `which` fills the disk (both `open`
    and `io.open`, which pathlib's write_text uses)."""
    import builtins
    import io

    real = io.open

    def opener(file, mode="r", *args, **kwargs):
        f = real(file, mode, *args, **kwargs)
        return _FullDisk(f) if which in os.fspath(file) and set(mode) & set("wxa") else f

    monkeypatch.setattr(builtins, "open", opener)
    monkeypatch.setattr(io, "open", opener)


@pytest.mark.parametrize("robot", ["p2us", "delta"])
@pytest.mark.parametrize("failing", [".urdf", ".loops.yaml", "a directory"])
def test_urdf_pair_is_written_as_one(robot, failing, capsys, workdir, monkeypatch):
    """`kinematics urdf ROBOT -o FILE` over an existing pair: the disk filling up while the URDF
    or, after it, the sidecar is written, or a sidecar path that is a directory, is one error
    line, and both files are left byte for byte as they were, with no temporary file beside them."""
    assert main(["urdf", robot, "-o", "d.urdf"]) == 0
    capsys.readouterr()
    if failing == "a directory":
        (workdir / "d.loops.yaml").unlink()
        (workdir / "d.loops.yaml").mkdir()
    before = {p: p.read_bytes() for p in workdir.iterdir() if p.is_file()}
    listing = _listing(workdir)
    with monkeypatch.context() as patch:
        if failing != "a directory":
            _disk_fills_while_writing(patch, "d" + failing if failing == ".urdf" else failing)
        code = main(["urdf", robot, "-o", "d.urdf", "--rod-spacing", "0.07"])
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and err.count("\n") == 1, err
    name = "d.urdf" if failing == ".urdf" else "d.loops.yaml"
    why = "it is a directory" if failing == "a directory" else "No space left on device"
    assert f"output: cannot write {name}: {why}" in err, err
    assert _listing(workdir) == listing
    assert {p: p.read_bytes() for p in before} == before
    if failing != "a directory":  # the disk has room again: the new pair replaces the old one
        assert main(["urdf", robot, "-o", "d.urdf", "--rod-spacing", "0.07"]) == 0
        assert _listing(workdir) == listing and (workdir / "d.urdf").read_bytes() != before[workdir / "d.urdf"]


# -- the process boundary: version, pipes, a full disk, Ctrl-C ---------------------------------------
def _kinematics(*argv: str) -> list[str]:
    return [sys.executable, "-m", "kinematics", *argv]


def test_version_from_package_metadata():
    from importlib.metadata import version

    proc = subprocess.run(_kinematics("--version"), capture_output=True, text=True)
    assert proc.returncode == 0 and proc.stdout == f"kinematics {version('kinematics')}\n" and proc.stderr == ""


def test_no_arguments_subprocess():
    proc = subprocess.run(_kinematics(), capture_output=True, text=True)
    assert proc.returncode == 0 and "COMMAND" in proc.stdout and proc.stderr == ""


def test_pipe_closed_early_is_quiet():
    # the report (~200 kB) is far larger than a pipe's buffer, so the writer is still writing
    # when the reader takes one line and closes the pipe: it must end quietly (141, like SIGPIPE)
    argv = _kinematics("singularities", "scara", "--angle-step-deg", "0.2", "--json")
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdout is not None and proc.stderr is not None
    assert proc.stdout.readline() == b"{\n"
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == 141 and err == ""
    shell = subprocess.run(f"{sys.executable} -m kinematics fk scara --q 0 0 | head -1", shell=True,
                           capture_output=True, text=True)
    assert shell.stderr == "" and shell.stdout.startswith("frame")


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
def test_full_disk_is_one_line():
    with open("/dev/full", "w") as full:
        proc = subprocess.run(_kinematics("fk", "scara", "--q", "0", "0"), stdout=full, stderr=subprocess.PIPE,
                              text=True)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "No space left" in proc.stderr and "Traceback" not in proc.stderr


def _interrupt(argv: list[str], after: float, group: bool = False,
               env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    # SIGINT back to its default in the child: a shell running the suite in the background starts
    # it with SIGINT ignored, and Python then installs no KeyboardInterrupt handler
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            env={**os.environ, **(env or {})},
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    time.sleep(after)
    if group:  # what a terminal's Ctrl-C does: SIGINT to the whole process group
        os.killpg(proc.pid, signal.SIGINT)
    else:
        proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    return subprocess.CompletedProcess(argv, proc.returncode, out, err)


# The guide command with every control step slowed by 1 ms: 30,000 steps take at least 30 s, so
# the interrupt at 6 s lands inside the computation however fast the machine (and after start-up
# however loaded it is), which a fixed step count cannot promise.
SLOW_GUIDE = """
import sys, time
from kinematics.guidance import controller as guidance
step = guidance.Controller.step
guidance.Controller.step = lambda self, *a, **k: (time.sleep(1e-3), step(self, *a, **k))[1]
from kinematics.cli.app import main
sys.exit(main(sys.argv[1:]))
"""


def test_ctrl_c_is_one_line():
    proc = _interrupt([sys.executable, "-c", SLOW_GUIDE, "guide", "--experiment", "3"], 6.0)
    assert proc.returncode == 130 and proc.stderr == "kinematics: interrupted\n", proc.stderr


@pytest.mark.slow
def test_ctrl_c_during_a_sweep_is_one_line():
    # enough designs (~200) that the sweep is still running when the interrupt arrives
    proc = _interrupt(_kinematics("sweep", "p2us", "--param", "b=0.3:0.35:20", "--param", "L=0.3:0.4:10", "--workers", "2"),
                      10.0, group=True)
    assert proc.returncode == 130 and proc.stderr == "kinematics: interrupted\n", proc.stderr


# Ctrl-C where Python's KeyboardInterrupt does not come back as itself. Inside a C library's
# callback into Python, as LLVM's object cache calls back while Numba compiles (a CI run's
# `workspace-volume ur5` interrupted 8 s in), ctypes swallows it and prints "Exception ignored
# ...", then the library either fails with an unrelated error or carries on as if no key had been
# pressed ("carries on" sleeps 10 s, then reports success). A compiled Numba kernel calling back
# into Python (`workspace-volume ur5`'s reachability search) returns it as the cause of a
# SystemError, itself the cause of the kernel's SystemError. And what the interrupted work left
# half-built can crash when freed (LLVM's modules from an interrupted compilation: a segfault after
# "interrupted" was printed), played by an object whose destructor reads address 0. The info
# command plays each, run through the process's entry point.
CTRL_C_HIDDEN = """
import ctypes, signal, sys, time
from kinematics.cli import info, run
where = sys.argv.pop()
class HalfBuilt:
    def __del__(self):
        ctypes.string_at(0)
def press():
    signal.raise_signal(signal.SIGINT)
    for _ in range(1000):  # the handler runs at the next check of pending signals
        pass
def command(args):
    if where == "in a kernel":
        try:
            try:
                press()
            except KeyboardInterrupt as ctrl_c:
                raise SystemError("<function _numba_unpickle> returned a result with an exception set") from ctrl_c
        except SystemError as inner:
            raise SystemError("CPUDispatcher(<function search>) returned a result with an exception set") from inner
    if where == "leaves a crash behind":
        half = HalfBuilt()
        press()
    if where == "with its reader gone":
        print("the start of a report")  # held in stdout's buffer (a pipe), whose reader is closed
        press()
    ctypes.CFUNCTYPE(None)(press)()
    if where == "fails":
        raise RuntimeError("no compiled object yet")
    time.sleep(10)
    print("finished")
    return 0
info.cmd_info = command
sys.argv[1:] = ["info", "scara"]
run()
"""


@pytest.mark.parametrize("where", ["fails", "carries on", "in a kernel", "leaves a crash behind"])
def test_ctrl_c_that_python_loses_is_one_line(where):
    proc = subprocess.run([sys.executable, "-c", CTRL_C_HIDDEN, where], capture_output=True, text=True, timeout=60,
                          preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert (proc.returncode, proc.stdout, proc.stderr) == (130, "", "kinematics: interrupted\n")


def test_ctrl_c_with_stdout_s_reader_gone_is_one_line():
    # the report's start still buffered when Ctrl-C comes, and the pipe's reader (`| head`) gone:
    # the entry point's last flush raised BrokenPipeError, a traceback after "interrupted"
    buffered = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}  # else the print meets the closed pipe
    proc = subprocess.Popen([sys.executable, "-c", CTRL_C_HIDDEN, "with its reader gone"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=buffered,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    proc.stdout.close()  # type: ignore[union-attr]
    err = proc.stderr.read()  # type: ignore[union-attr]
    assert (proc.wait(timeout=60), err) == (130, "kinematics: interrupted\n")


def test_a_system_error_without_ctrl_c_is_not_an_interrupt(monkeypatch):
    from kinematics.cli import info

    def broken(args: object) -> int:
        raise SystemError("a bug, not an interrupt")

    monkeypatch.setattr(info, "cmd_info", broken)
    with pytest.raises(SystemError, match="a bug"):
        main(["info", "scara"])


@pytest.mark.slow
@pytest.mark.parametrize("cache", ["as it is", "empty"])
def test_ctrl_c_during_a_serial_arm_volume_is_one_line(cache, tmp_path):
    # the UR5's volume at rtol 1e-7 from 2.5 mm runs ~40 s (rtol 1e-5 now ends in ~5 s), so the
    # interrupt at 8 s lands inside the compiled reachability search (it came out as a 76-line
    # SystemError traceback, exit 1) or, with an empty kernel cache, inside Numba's compilation
    # (4 s; where LLVM's callbacks swallow it)
    env = {"NUMBA_CACHE_DIR": str(tmp_path)} if cache == "empty" else {}
    proc = _interrupt(_kinematics("workspace-volume", "ur5", "--rtol", "1e-7", "--step", "0.0025"), 4.0 if env else 8.0,
                      env=env)
    assert proc.returncode == 130 and proc.stderr == "kinematics: interrupted\n", proc.stderr
