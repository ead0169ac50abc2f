"""The command line through `main([...])` and as a real subprocess."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from kinematics.cli.app import main
from kinematics.model.robot import load_robot

from .conftest import COMMANDS, write_2r_urdf


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def run_json(capsys, *argv):
    code, out, err = run(capsys, *argv, "--json")
    return code, json.loads(out), err


def test_help_lists_every_command(capsys):
    """`kinematics --help` lists exactly the documented commands (conftest.COMMANDS, written by hand)."""
    assert main(["--help"]) == 0  # main returns the status, argparse's exit included
    out = capsys.readouterr().out
    listed = re.findall(r"^    ([a-z][a-z-]*)(?: |$)", out, flags=re.M)  # the COMMAND list's entries
    assert sorted(listed) == sorted(COMMANDS)


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_takes_json(capsys, command):
    """The README: "Every command takes `--json`"."""
    assert main([command, "--help"]) == 0
    usage = capsys.readouterr().out.split("\n\n")[0]
    assert usage.startswith(f"usage: kinematics {command} ") and "[--json]" in usage


def test_info(capsys):
    code, data, _ = run_json(capsys, "info", "scara")
    assert code == 0
    assert data["parameters"] == {"l1": 0.4, "l2": 0.3}
    assert [j["name"] for j in data["joints"]] == ["joint1", "joint2"]
    assert data["planar"] and data["plane_axes"] == ["x", "y"]
    assert data["parsers_agree"]["max_position_error"] <= 1e-12
    code, out, _ = run(capsys, "info", "scara")
    assert "l1" in out and "joint2" in out


def test_fk_planar_and_spatial(capsys):
    code, data, _ = run_json(capsys, "fk", "scara", "--q", "0", "0")
    assert code == 0 and data["position"] == pytest.approx([0.7, 0.0])
    code, deg, _ = run_json(capsys, "fk", "scara", "--q", "90", "0", "--degrees")
    assert deg["position"] == pytest.approx([0.0, 0.7], abs=1e-15)
    q = [0.1, -1.2, 1.0, 0.3, 0.2, 0.1]
    code, data, _ = run_json(capsys, "fk", "ur5", "--q", *map(repr, q))
    assert code == 0 and data["frame"] == "tool0"  # the UR's flange frame
    # Pinocchio on the same URDF, read here (six revolute joints: q is the configuration)
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(load_robot("ur5").urdf_path))
    assert model.nq == 6
    pose = model.createData()
    pin.framesForwardKinematics(model, pose, np.array(q))
    M = pose.oMf[model.getFrameId("tool0")]
    # JSON carries repr-exact floats; the CLI and this call compose the same placements: ~1e-16
    np.testing.assert_allclose(data["position"], M.translation, rtol=0, atol=1e-12)
    np.testing.assert_allclose(data["rotation"], M.rotation, rtol=0, atol=1e-12)


def test_ik_json_and_exit_codes(capsys):
    code, data, _ = run_json(capsys, "ik", "scara", "--position", "0.4", "0.3")
    assert code == 0 and data["reachable"] is True
    assert {s["elbow"] for s in data["solutions"]} == {"up", "down"}
    assert all(set(s) >= {"q", "elbow", "within_limits"} for s in data["solutions"])
    code, data, _ = run_json(capsys, "ik", "scara", "--position", "0.9", "0")
    assert code == 1 and data["reachable"] is False and "outer radius" in data["reason"]
    code, out, _ = run(capsys, "ik", "scara", "--position", "0.9", "0")
    assert code == 1 and "NOT reachable" in out


def test_jacobian_and_manipulability(capsys):
    code, data, _ = run_json(capsys, "jacobian", "scara", "--q", "0", "0")
    assert code == 0
    np.testing.assert_allclose(data["jacobian"], [[0, 0], [0.7, 0.3]], atol=1e-15)
    code, data, _ = run_json(capsys, "manipulability", "scara", "--q", "0", "0")
    assert set(data) >= {"jacobian", "radii", "directions", "yoshikawa", "condition_number", "singular"}
    assert data["radii"][0] == pytest.approx(0, abs=1e-15) and round(data["radii"][1], 4) == 0.7616
    assert data["singular"] is True and data["condition_number"] is None
    code, data, _ = run_json(capsys, "manipulability", "ur5", "--q", "0.1", "-1.2", "1", "0.3", "0.2", "0.1")
    assert len(data["radii"]) == 3 and set(data["rotational"]) >= {"radii", "directions", "singular"}
    code, data, _ = run_json(capsys, "manipulability", "ur5", "--q", "0", "-1", "1", "0", "0", "0",
                             "--frame", "wrist_1_link")
    assert data["frame"] == "wrist_1_link"


def test_human_reports(capsys):
    for argv in (["manipulability", "scara", "--q", "0.3", "1.2"], ["jacobian", "ur5", "--q", *["0.1"] * 6],
                 ["fk", "ur5", "--q", *["0.1"] * 6]):
        code, out, err = run(capsys, *argv)
        assert code == 0 and out.strip() and not err


def bad_inputs(tmp_path):
    missing = tmp_path / "missing.urdf"
    malformed = tmp_path / "malformed.urdf"
    malformed.write_text("<robot><link name='a'>")
    return [
        (["fk", "scara", "--q", "0.1"], "2 degrees of freedom"),
        (["fk", "scara", "--q", "0.1", "nan"], "finite"),
        (["manipulability", "scara", "--q", "inf", "0"], "finite"),
        (["fk", str(missing), "--q", "0"], "no such file"),
        (["info", str(malformed)], "malformed XML"),
        (["fk", "nosuchbot", "--q", "0"], "unknown robot"),
        (["fk", "scara", "--q", "0", "0", "--frame", "nope"], "unknown frame"),
        (["ik", "scara", "--position", "0.1", "nan"], "finite"),
        (["ik", "scara", "--position", "0.1"], "give X Y"),
        (["ik", "ur5", "--position", "0.1", "0.2", "0.3"], "for closed loops by the batched solver; this one is neither"),
        (["jacobian", "scara"], "needs joint values"),
        (["fk", "scara", "--q", "zero", "1"], "expected a number"),
        (["nosuchcommand"], "invalid choice"),
    ]


def test_bad_input_in_process(capsys, tmp_path):
    for argv, needle in bad_inputs(tmp_path):
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse-level errors
            code = exc.code
        out, err = capsys.readouterr()
        assert code == 2, argv
        assert err.count("\n") == 1 and needle in err, (argv, err)
        assert "Traceback" not in err and out == ""


@pytest.mark.parametrize("case", range(4))
def test_subprocess_exit_codes(tmp_path, case):
    argv, needle = bad_inputs(tmp_path)[[0, 3, 5, 11][case]]
    proc = subprocess.run([sys.executable, "-m", "kinematics", *argv], capture_output=True, text=True)
    assert proc.returncode == 2 and needle in proc.stderr
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr


def test_subprocess_console_script_ok_and_unreachable():
    ok = subprocess.run([sys.executable, "-m", "kinematics", "ik", "scara", "--position", "0.4", "0.3", "--json"],
                        capture_output=True, text=True)
    assert ok.returncode == 0 and json.loads(ok.stdout)["reachable"] is True
    no = subprocess.run([sys.executable, "-m", "kinematics", "ik", "scara", "--position", "0", "0.05", "--json"],
                        capture_output=True, text=True)
    assert no.returncode == 1 and json.loads(no.stdout)["reachable"] is False and no.stderr == ""


def test_any_urdf_path(capsys, tmp_path):
    path = tmp_path / "arm.urdf"
    write_2r_urdf(path, 1.0, 0.5)
    code, data, _ = run_json(capsys, "ik", str(path), "--position", "1.5", "0")
    assert code == 0 and data["solutions"][0]["q"] == pytest.approx([0, 0], abs=1e-12)


def _q_help(capsys, command):
    """--q's description in `kinematics COMMAND --help` (unwrapped), up to the next option."""
    assert main([command, "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    start = text.index("--q Q [Q ...] joint values")
    return text[start:text.index(" --degrees", start)]


def test_q_help_says_which_robots_take_it(capsys):
    # manipulability refuses every closed loop, and the Delta's Jacobian (like the p2us') is taken
    # at --position: --q's help must not promise actuator values there
    assert "closed-loop" not in _q_help(capsys, "manipulability")
    assert "p2us, delta: not used" in _q_help(capsys, "jacobian")
    assert main(["jacobian", "delta", "--q", "0.4", "0.4", "0.4"]) == 2
    assert main(["manipulability", "delta", "--q", "0.4", "0.4", "0.4"]) == 2


def test_workspace_mesh_help_names_the_delta(capsys, tmp_path):
    # the help said "p2us:" alone, yet the Delta's boundary is meshed too
    assert main(["workspace-mesh", "--help"]) == 0
    assert "p2us, delta" in " ".join(capsys.readouterr().out.split())
    assert main(["workspace-mesh", "delta", "-o", str(tmp_path / "d.stl"), "--step", "0.1"]) == 0


@pytest.mark.parametrize("argv", [
    ("workspace-volume", "p2us", "--step", "0.05", "--rtol", "0.1"),
    ("singularities", "p2us", "--step", "0.05"),
    ("usable-workspace", "p2us", "--shape", "cube", "--step", "0.05"),
    ("dexterity", "p2us", "--samples", "64", "--replicates", "2"),
    ("show", "p2us", "--workspace", "--step", "0.05", "--export", "{tmp}/v.html"),
    # a generic closed loop's ik: the batched solver (it was silent for the minutes of its compilation)
    ("ik", str(Path(__file__).parent / "models" / "fivebar_gepetto" / "robot.urdf"), "--position", "0.1", "0.3"),
])
def test_compile_notice_before_uncached_kernels(capsys, monkeypatch, tmp_path, argv):
    """On a terminal, every command that runs a mechanism's compiled kernels says "compiling kernels
    (first run only)" when Numba's cache lacks them (a generic closed loop's solver: minutes of
    silence otherwise); told the cache is full, none does. The terminal and the cache's state are
    simulated (the kernels are in fact cached by then: the runs stay quick)."""
    from kinematics import jit
    from kinematics.cli import report

    argv = tuple(a.replace("{tmp}", str(tmp_path)) for a in argv)
    monkeypatch.setattr(report, "show_progress", lambda args: not getattr(args, "json", False))
    for cached, want in ((False, 1), (True, 0)):
        monkeypatch.setattr(jit, "cached", lambda kernels, cached=cached: cached)
        code, _, err = run(capsys, *argv)
        assert code == 0, err
        assert err.count("compiling kernels (first run only)") == want, err
