"""`workspace-volume`, `singularities` and `sweep` through main(); the sweep on a real Dask cluster."""

from __future__ import annotations

import math
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from kinematics.analyses import sweep as sw
from kinematics.errors import InvalidInputError, UnknownParameterError

from .test_cli import run, run_json

KEYS = {"modes", "bbox", "points_evaluated", "singular_points", "step_m", "seconds"}


def test_workspace_volume_p2us(capsys, tmp_path):
    pts, png = tmp_path / "inside.npy", tmp_path / "ws.png"
    code, d, _ = run_json(capsys, "workspace-volume", "p2us", "--step", "0.03", "--rtol", "0.01",
                          "--points", str(pts), "--plot", str(png))
    assert code == 0 and KEYS | {"volume_m3", "error_estimate", "converged"} <= set(d)
    assert 0 < d["error_estimate"] <= 0.01 * d["volume_m3"] and d["converged"]
    assert set(d["modes"]) == set(__import__("kinematics.mechanisms.p2us.closed_form", fromlist=["MODES"]).MODES)
    assert d["singular_points"] == [] and d["paper_volume_m3"] == 0.13397
    inside = np.load(pts)
    assert inside.shape[1] == 3 and len(inside) > 100
    assert np.all(inside >= np.array(d["bbox"][0]) - 0.03) and np.all(inside <= np.array(d["bbox"][1]) + 0.03)
    assert png.read_bytes()[:4] == b"\x89PNG"
    code, out, _ = run(capsys, "workspace-volume", "p2us", "--step", "0.03", "--rtol", "0", "--limits", "actuators")
    assert code == 0 and "union" in out and "paper B: 0.13397" in out and "bounding box" in out
    assert "error estimate [m^3]" in out and "b [m]" in out and "beta [deg]" in out and "working mode:" in out


def test_workspace_volume_scara(capsys, tmp_path):
    csv = tmp_path / "pts.csv"
    code, d, _ = run_json(capsys, "workspace-volume", "scara", "--step", "0.02", "--points", str(csv))
    assert code == 0 and KEYS - {"modes"} | {"area_m2", "error_estimate", "converged", "elbows"} <= set(d)
    assert 0 < d["error_estimate"] <= 1e-3 * d["area_m2"]
    assert all(abs(np.hypot(*p["position"]) - 0.7) < 1e-9 for p in d["singular_points"])
    assert csv.read_text().startswith("x,y\n")


@pytest.mark.parametrize(("argv", "needle"), [
    (["--limits", "none"], "invalid choice"),
    (["--modes", "+*+"], "unknown mode"),
    (["--step", "-1"], "positive"),
    (["--step", "nan"], "positive"),
    (["--step", "1e-6"], "limit"),
])
def test_workspace_volume_bad_input(capsys, argv, needle):
    try:
        code, out, err = run(capsys, "workspace-volume", "p2us", *argv)
    except SystemExit as exc:  # argparse's own checks exit through _Parser.error
        code = exc.code
        out, err = capsys.readouterr()
    assert code == 2 and out == "" and needle in err and len(err.strip().splitlines()) == 1


def test_workspace_volume_says_what_a_mechanism_lacks(capsys):
    rssr = str(Path(__file__).parent / "models" / "rssr.urdf")
    code, _, err = run(capsys, "workspace-volume", rssr)  # one degree of freedom: a 1D task space
    assert code == 2 and "2- or 3-dimensional" in err
    code, _, err = run(capsys, "singularities", rssr)
    assert code == 2 and "3D grid" in err and "1-dimensional" in err
    code, _, err = run(capsys, "usable-workspace", "ur5", "--shape", "cube")
    assert code == 2 and "needs its mechanism's ik" in err and "it provides: fk, margin, reach_search, velocity" in err


REVOLVED = str(Path(__file__).parent / "models" / "arm3r_revolved.urdf")
REVOLVED_M3 = 0.331334  # closed form of its solid of revolution (docs/serial-workspace.md, test_serial_workspace)


def test_workspace_volume_serial(capsys, tmp_path):
    """A serial arm goes through the one volume engine: the closed loops' report and keys."""
    csv = tmp_path / "pts.csv"
    code, d, _ = run_json(capsys, "workspace-volume", REVOLVED, "--step", "0.02", "--rtol", "1e-4", "--points", str(csv))
    assert code == 0 and d["method"] == "columns" and d["family"] == "serial"
    assert {"volume_m3", "error_estimate", "points_evaluated", "seconds", "columns", "bbox"} <= set(d)
    assert abs(d["volume_m3"] - REVOLVED_M3) <= max(d["error_estimate"], 1e-6)  # REVOLVED_M3 has 6 digits
    pts = np.loadtxt(csv, delimiter=",", skiprows=1)
    assert csv.read_text().startswith("x,y,z\n") and pts.shape[1] == 3 and len(pts) > 1000
    # every listed point lies in the solid: tip within [r(1.5), r(0.3)] of the shoulder (0.3 m up)
    r = np.linalg.norm(pts - [0, 0, 0.3], axis=1)
    assert np.all((r >= math.sqrt(0.4**2 + 0.25**2 + 0.2 * math.cos(1.5)) - 1e-9)
                  & (r <= math.sqrt(0.4**2 + 0.25**2 + 0.2 * math.cos(0.3)) + 1e-9))


def test_workspace_volume_serial_report_does_not_claim_a_singular_scan(capsys):
    """A serial arm's volume run scans no singular locus: the report says so instead of '0 inside'."""
    code, out, _ = run(capsys, "workspace-volume", REVOLVED, "--step", "0.05", "--rtol", "1e-2")
    assert code == 0 and "not scanned" in out and "singular points inside" not in out


def test_singularities_serial(capsys):
    """The sample's positions are the images of its joint values (the base joint at its listed
    value for the UR5's solid of revolution), by forward kinematics."""
    from kinematics.generic.serial import forward_kinematics
    from kinematics.model.robot import load_robot

    code, d, _ = run_json(capsys, "singularities", "ur5", "--max-points", "20000")
    assert code == 0 and d["singular_boxes"] > 0 and 0 < len(d["singular_points"]) <= 200
    robot = load_robot("ur5")
    for p in d["singular_points"][::20]:
        x = forward_kinematics(robot, robot.configuration(p["q"])).position
        # 1e-9 m: one FK in double precision, far below any cell
        assert np.abs(x - np.array(p["position"])).max() < 1e-9


def test_singularities_p2us(capsys, tmp_path):
    png = tmp_path / "loci.png"
    code, d, _ = run_json(capsys, "singularities", "p2us", "--step", "0.03", "--paper-scan", "--plot", str(png))
    assert code == 0 and {"singularities", "singular_points", "any_inside_workspace", "paper_scan"} <= set(d)
    assert d["paper_scan"]["actuator_triples"] == 512 and png.exists()
    code, out, _ = run(capsys, "singularities", "p2us", "--step", "0.03", "--limits", "actuators")
    assert code == 0 and "type_II" in out


def test_singularities_scara(capsys):
    code, d, _ = run_json(capsys, "singularities", "scara", "--angle-step-deg", "5")
    assert code == 0 and d["theta2_zero_within_limits"] is True and d["singular_points"]


def test_sweep_parsing():
    a = sw.Axis.parse("b=0.25:0.40:16")
    assert (a.name, a.start, a.stop, a.count) == ("b", 0.25, 0.40, 16)
    assert sw.Axis.parse("L=0.3").values().tolist() == [0.3]
    with pytest.raises(UnknownParameterError, match="stroke_max"):
        sw.Axis.parse("q=1:2:3")
    with pytest.raises(InvalidInputError):
        sw.Axis.parse("b=1:2")
    with pytest.raises(InvalidInputError):
        sw.Axis.parse("b=0.3:0.2:x")


def test_sweep_cli_errors(capsys):
    code, _, err = run(capsys, "sweep", "p2us")
    assert code == 2 and "--param: give at least one" in err
    code, _, err = run(capsys, "sweep", "p2us", "--param", "L=-0.3")
    assert code == 2 and "L: must be a positive length [m], got -0.3" in err


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def dask_cluster(tmp_path_factory):
    """A real dask scheduler and two single-threaded worker processes on loopback."""
    bin_dir = Path(sys.executable).parent
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    log = tmp_path_factory.mktemp("dask")
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    procs = [subprocess.Popen([str(bin_dir / "dask"), "scheduler", "--host", "127.0.0.1", "--port", str(port),
                               "--no-dashboard"], stdout=open(log / "s.log", "w"), stderr=subprocess.STDOUT, env=env)]
    for k in range(2):
        procs.append(subprocess.Popen([str(bin_dir / "dask"), "worker", address, "--nworkers", "1", "--nthreads", "1",
                                       "--no-dashboard", "--name", f"w{k}"],
                                      stdout=open(log / f"w{k}.log", "w"), stderr=subprocess.STDOUT, env=env))
    try:
        from distributed import Client

        deadline = time.monotonic() + 60
        while True:
            try:
                with Client(address, timeout="2s") as c:
                    c.wait_for_workers(2, timeout=max(1.0, deadline - time.monotonic()))
                break
            except (OSError, TimeoutError):
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.5)
        yield address
    finally:
        for p in procs:
            p.terminate()
        for p in procs:
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()


def test_sweep_on_a_real_cluster_equals_in_process(capsys, tmp_path, dask_cluster):
    from distributed import Client

    axes = [sw.Axis.parse("b=0.30:0.35:2"), sw.Axis.parse("L=0.32:0.36:2")]
    with Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0") as local:
        rows = sw.run(axes, client=local, step=0.03, progress=False)
    expected = sw.to_csv(rows)
    out = tmp_path / "sweep.csv"
    code, d, _ = run_json(capsys, "sweep", "p2us", "--param", "b=0.30:0.35:2", "--param", "L=0.32:0.36:2",
                          "--step", "0.03", "--scheduler", dask_cluster, "--out", str(out))
    assert code == 0 and d["scheduler"] == dask_cluster
    assert out.read_text() == expected
    assert [r["design"] for r in d["designs"]] == [0, 1, 2, 3]
    vols = [r["volume_m3"] for r in rows]
    assert vols[2] > vols[0]  # a larger base gives a larger workspace here
    assert all(0 <= r["singularity_free_fraction"] <= 1 and 0 < r["conditioning_index"] <= 1 for r in rows)
    assert "seconds" not in expected


def test_workspace_volume_names_the_branches_that_did_not_converge(capsys, monkeypatch):
    """When the half-step check disagrees on some branches only (the Delta's slivers with `--limits
    actuators` do, in ~90 s), the warning and the report name them and the JSON marks them. The
    measurement is substituted by a real one of the same shape: a slab the 2 cm columns step over, the check allowed one halving
    (tests/test_volume_engine.py) as branch '+++', a ball as the union."""
    import kinematics.analyses.workspace as wsmod
    from kinematics.analyses.columns import column_volume
    from kinematics.analyses.columns import engine as columns

    def margin(p):
        ball = 0.5 - np.linalg.norm(p, axis=1)
        return np.stack([np.minimum(0.005 - np.abs(p[:, 2] - 0.02), ball), ball], axis=1)

    monkeypatch.setattr(columns, "CHECK_HALVINGS", 1)  # one halving: the 1 cm run sees it, 2 cm not

    r = column_volume(margin, -np.full(3, 0.55), np.full(3, 0.55), step=0.02, rtol=1e-3, axis=2, check=True)
    monkeypatch.setattr(wsmod, "measure_workspace",
                        lambda mech, **kw: wsmod.Workspace("delta", False, ("+++", "union"), kw["limits"], r, 0.1))
    code, d, err = run_json(capsys, "workspace-volume", "delta", "--modes=+++", "--limits", "actuators",
                            "--step", "0.1")
    assert code == 0 and not d["converged"] and d["modes"]["+++"]["converged"] is False
    assert "not converged on 1 of 2 targets (+++: the run at half the step disagreed" in err
    code, out, err = run(capsys, "workspace-volume", "delta", "--modes=+++", "--limits", "actuators", "--step", "0.1")
    assert code == 0 and "NOT converged" in out and "not converged on 1 of 2 targets (+++:" in out


def test_an_empty_workspace_reports_no_inf_or_nan(capsys):
    """example-robot-data's double pendulum: its tool frame is the second joint's, so it reaches a
    circle, area 0. The report printed "inf relative" and a box of "[nan, nan] .. [nan, nan]"."""
    from .test_cli import run

    code, out, err = run(capsys, "workspace-volume", "double_pendulum", "--range", "joint1=-pi:pi",
                         "--range", "joint2=-pi:pi", "--step", "0.05", "--rtol", "0.05")
    assert code == 0, err
    assert "area [m^2]                         : 0 +/- 0" in out
    assert "nan" not in out.lower() and "inf" not in out.lower(), out


POLAR_ARM = """<robot name="polar"><link name="base"/><link name="l1"/><link name="l2"/><link name="tip"/>
<joint name="turn" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
<joint name="reach" type="prismatic"><parent link="l1"/><child link="l2"/><axis xyz="1 0 0"/>
<limit lower="0.1" upper="0.5" effort="1" velocity="1"/></joint>
<joint name="t" type="fixed"><parent link="l2"/><child link="tip"/><origin xyz="0.05 0 0"/></joint></robot>
"""


def test_report_keeps_a_prismatic_joints_limits_in_metres(capsys, tmp_path):
    # the report shows revolute limits in degrees; a prismatic joint's [0.1, 0.5] m stays in m,
    # not 5.72958 and 28.6479 "deg" (0.1 and 0.5 taken for radians)
    urdf = tmp_path / "polar.urdf"
    urdf.write_text(POLAR_ARM)
    code, out, _ = run(capsys, "workspace-volume", str(urdf), "--step", "0.05", "--rtol", "0.1")
    lines = {ln.split(":")[0].strip(): ln.split(":", 1)[1].strip() for ln in out.splitlines() if ln.startswith(("lower", "upper"))}
    assert code == 0 and lines == {"lower [deg; m for prismatic]": "[-57.2958, 0.1]",
                                   "upper [deg; m for prismatic]": "[57.2958, 0.5]"}


@pytest.mark.parametrize("zero", ["0", "0.00", "-0", "0e0"])
def test_rtol_zero_in_any_spelling_is_the_default_tolerance(capsys, zero):
    # --rtol's help: "0: 1e-2"; a zero is a zero however written, not "must be positive"
    code, d, err = run_json(capsys, "workspace-volume", "scara", "--step", "0.05", "--rtol", zero)
    assert code == 0 and d["rtol"] == 1e-2, err


def test_a_step_too_coarse_to_see_anything_is_told_to_get_finer(capsys):
    # a 10 m step over the ur5's 2.5 m reach finds no inside point: the warning told the user to
    # try a *larger* step
    from kinematics.cli import main

    assert main(["workspace-volume", "ur5", "--step", "10"]) == 0
    err = capsys.readouterr().err
    assert "nothing was found inside" in err and "try a smaller --step" in err and "larger" not in err
