"""``ik5r fk`` and ``ik5r solve``: CSV contract, round trips with the three solvers, malformed
files (exit 2, FILE:LINE), NaN rows, --all and --near."""

from __future__ import annotations

import csv
import json
import math
import shutil
import subprocess
import sys
from importlib import resources

import numpy as np
import pytest

from ik5r.core import reference as ref
from ik5r.core import status as st
from ik5r.core.arm import load_arm
from ik5r.core.fxconfig import load_config
from ik5r.tools.cli import main

ARM = load_arm()
POSE_HEADER = "px,py,pz,nx,ny,nz,ox,oy,oz,ax,ay,az"
HARMLESS = st.SINGULAR_ELBOW | st.SINGULAR_BASE


def _read(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def _write_joints(path, q):
    lines = ["q1,q2,q3,q4,q5"] + [",".join(repr(float(v)) for v in row) for row in q]
    path.write_text("\n".join(lines) + "\n")


def _joints(rows):
    return np.array([[float(r[f"q{j}"]) for j in range(1, 6)] for r in rows])


@pytest.fixture(scope="module")
def poses(tmp_path_factory):
    """200 random joint vectors (reachable by construction) and their fk CSV."""
    tmp = tmp_path_factory.mktemp("cli")
    q = ref.random_joints(ARM, 200, np.random.default_rng(21))
    joints = tmp / "joints.csv"
    _write_joints(joints, q)
    out = tmp / "poses.csv"
    assert main(["fk", str(joints), "-o", str(out)]) == 0
    return q, out


def test_fk_output_is_exact_reference(poses):
    q, path = poses
    rows = _read(path)
    assert list(rows[0]) == POSE_HEADER.split(",")
    got = np.array([[float(r[c]) for c in POSE_HEADER.split(",")] for r in rows])
    assert np.array_equal(got, ref.fk_pose(ARM, q))      # repr precision: bit for bit


def test_fk_to_stdout(tmp_path, capsys):
    joints = tmp_path / "j.csv"
    _write_joints(joints, [[0.0, -math.pi / 2, 0.0, -math.pi / 2, 0.0]])
    assert main(["fk", str(joints)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == POSE_HEADER
    values = [float(v) for v in lines[1].split(",")]
    assert np.allclose([values[0], values[1], values[2]], [-2.1, 0, 34], rtol=0, atol=1e-12)
    assert np.allclose(values[9:], [0, 0, 1], rtol=0, atol=1e-12)


@pytest.mark.parametrize("solver", ["float", "fixed", "c"])
def test_fk_solve_round_trip(poses, tmp_path, solver):
    if solver == "c" and shutil.which("cc") is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler")
    q, path = poses
    out = tmp_path / "out.csv"
    assert main(["solve", str(path), "-o", str(out), "--solver", solver, "--all"]) == 0
    rows = _read(out)
    header = list(rows[0])
    base = ["row", "branch", "q1", "q2", "q3", "q4", "q5", "status", "residual_cm", "residual_rad"]
    if solver == "float":
        assert header == base
        tol = 1e-7
    else:
        assert header == base + [f"q{j}_raw" for j in range(1, 6)] + ["status_bits"]
        tol = 1e-5           # q32: the angles of a 32-bit solver, errors of a few 1e-7 rad
    # reachable poses: the written joints reach the tool point and the approach
    assert max(float(r["residual_cm"]) for r in rows) <= (1e-9 if solver == "float" else 1e-5)
    assert max(float(r["residual_rad"]) for r in rows) <= (1e-9 if solver == "float" else 1e-6)
    index = np.array([int(r["row"]) for r in rows])
    got = _joints(rows)
    status = [r["status"] for r in rows]
    assert sorted(set(index.tolist())) == list(range(len(q)))
    for i in range(len(q)):
        mine = got[index == i]
        dq = np.abs(ref.wrap(mine - q[i])).max(axis=-1)
        assert dq.min() <= tol, (i, dq.min())
    if solver != "float":
        cfg = load_config(None)
        raw = np.array([[int(r[f"q{j}_raw"]) for j in range(1, 6)] for r in rows])
        assert np.array_equal(got, raw * 2.0 ** -cfg.frac_angle)
        bits = [int(r["status_bits"]) for r in rows]
        assert [st.describe(b) for b in bits] == status
    # --all lists valid branches only (all poses are reachable)
    assert all(s in ("ok", "singular_elbow") for s in status)


def test_fixed_and_c_agree_bit_for_bit(poses, tmp_path):
    if shutil.which("cc") is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler")
    _, path = poses
    outs = {}
    for solver in ("fixed", "c"):
        out = tmp_path / f"{solver}.csv"
        assert main(["solve", str(path), "-o", str(out), "--solver", solver]) == 0
        outs[solver] = out.read_text()
    assert outs["fixed"] == outs["c"]


def test_default_branch_is_float_choice(poses, tmp_path):
    q, path = poses
    out = tmp_path / "float.csv"
    assert main(["solve", str(path), "-o", str(out)]) == 0
    rows = _read(out)
    assert [int(r["row"]) for r in rows] == list(range(len(q)))
    p, n, o, a = ref.fk(ARM, q)
    res = ref.ik(ARM, p, a, n, o)
    assert [int(r["branch"]) for r in rows] == res.choose().tolist()
    assert np.array_equal(_joints(rows), res.best()[0])
    out_fx = tmp_path / "fixed.csv"
    assert main(["solve", str(path), "-o", str(out_fx), "--solver", "fixed"]) == 0
    assert [int(r["branch"]) for r in _read(out_fx)] == res.choose().tolist()


def test_near_selects_branch(tmp_path):
    q = [-2.5, 1.0, -2.0, 0.3, 3.0]           # front shoulder, elbow down (branch 1)
    joints = tmp_path / "j.csv"
    _write_joints(joints, [q])
    poses = tmp_path / "p.csv"
    assert main(["fk", str(joints), "-o", str(poses)]) == 0
    out = tmp_path / "o.csv"
    assert main(["solve", str(poses), "-o", str(out)]) == 0
    assert _read(out)[0]["branch"] == "0"
    near = ",".join(repr(v) for v in q)
    for solver in ("float", "fixed"):
        assert main(["solve", str(poses), "-o", str(out), "--solver", solver, f"--near={near}"]) == 0
        row = _read(out)[0]
        assert row["branch"] == "1"
        assert np.abs(ref.wrap(_joints([row])[0] - q)).max() <= (1e-7 if solver == "float" else 1e-5)


def test_position_only_poses_use_near_q5(tmp_path):
    q = [0.4, -0.3, 1.2, 0.2, 0.0]
    p, _, _, a = ref.fk(ARM, np.array(q))
    poses = tmp_path / "p.csv"
    poses.write_text("px,py,pz,ax,ay,az\n" + ",".join(repr(float(v)) for v in [*p, *a]) + "\n")
    out = tmp_path / "o.csv"
    assert main(["solve", str(poses), "-o", str(out), "--near=0.4,-0.3,1.2,0.2,0.75"]) == 0
    row = _read(out)[0]
    assert float(row["q5"]) == 0.75 and row["status"] == "ok"
    assert np.abs(_joints([row])[0, :4] - q[:4]).max() <= 1e-7


def test_nan_row_is_invalid_others_written(poses, tmp_path):
    _, path = poses
    lines = path.read_text().splitlines()
    lines[3] = ",".join(["nan"] + lines[3].split(",")[1:])
    lines[5] = ",".join(lines[5].split(",")[:-1] + ["inf"])
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines[:8]) + "\n")
    for solver in ("float", "fixed", "c"):
        out = tmp_path / f"{solver}.csv"
        assert main(["solve", str(bad), "-o", str(out), "--solver", solver]) == 0
        rows = _read(out)
        assert [int(r["row"]) for r in rows] == list(range(7))
        for i, r in enumerate(rows):
            if i in (2, 4):
                assert r["status"] == "invalid" and math.isnan(float(r["q1"]))
                if solver != "float":
                    assert r["status_bits"] == str(st.INVALID) and r["q1_raw"] == "0"
            else:
                assert r["status"] in ("ok", "singular_elbow")
    out = tmp_path / "all.csv"
    assert main(["solve", str(bad), "-o", str(out), "--all"]) == 0
    rows = [r for r in _read(out) if r["row"] == "2"]
    assert [r["branch"] for r in rows] == ["0", "1", "2", "3"]
    assert all(r["status"] == "invalid" for r in rows)


def test_all_writes_every_branch_when_none_valid(tmp_path):
    poses = tmp_path / "p.csv"
    poses.write_text("px,py,pz,ax,ay,az\n100,0,0,0,0,1\n0,0,10,0,0,1\n")
    out = tmp_path / "o.csv"
    assert main(["solve", str(poses), "-o", str(out), "--all", "--near=0.5,0,0,0,0"]) == 0
    rows = _read(out)
    far = [r for r in rows if r["row"] == "0"]
    assert [r["branch"] for r in far] == ["0", "1", "2", "3"]
    assert all("unreachable" in r["status"] for r in far)
    axis = [r for r in rows if r["row"] == "1"]
    assert [r["status"] for r in axis] == ["singular_base"] * 4
    assert float(axis[0]["q1"]) == 0.5        # q1 free: --near's q1
    for solver in ("fixed", "c"):
        assert main(["solve", str(poses), "-o", str(out), "--all", "--solver", solver]) == 0
        rows = _read(out)
        assert [r["branch"] for r in rows if r["row"] == "0"] == ["0", "1", "2", "3"]
        assert all("singular_base" in r["status"] for r in rows if r["row"] == "1")


def test_saturated_input_sets_bit(tmp_path):
    poses = tmp_path / "p.csv"
    poses.write_text("px,py,pz,ax,ay,az\n1000,0,0,0,0,1\n10,0,5,1,0,0\n")   # q32 lengths < 128 cm
    out = tmp_path / "o.csv"
    assert main(["solve", str(poses), "-o", str(out), "--solver", "fixed"]) == 0
    rows = _read(out)
    assert int(rows[0]["status_bits"]) & st.SATURATED
    assert not int(rows[1]["status_bits"]) & st.SATURATED


@pytest.mark.parametrize("text, line, needle", [
    ("px,py,pz,ax,ay\n1,2,3,4,5\n", 1, "field 'az': missing column"),
    ("px,py,pz,ax,ay,az,nx\n1,2,3,0,0,1,0\n", 1, "field 'ny'"),
    ("px,py,pz,ax,ay,az\n1,2,3,0,0,1\n1,2,abc,0,0,1\n", 3, "field 'pz': not a number: 'abc'"),
    ("px,py,pz,ax,ay,az\n1,2,3,0,0,1\n\n1,2,3,0,0\n", 4, "expected 6 fields, got 5"),
    ("px,py,pz,ax,ay,az\n1,2,3,0,0,1,7\n", 2, "expected 6 fields, got 7"),
    ("px,py,pz,ax,ay,az\n1,,3,0,0,1\n", 2, "field 'py': not a number: ''"),
    ("", 1, "empty file"),
])
def test_malformed_poses_exit_2(tmp_path, capsys, text, line, needle):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    assert main(["solve", str(path)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.startswith(f"{path}:{line}: "), captured.err
    assert needle in captured.err


def test_malformed_joints_exit_2(tmp_path, capsys):
    path = tmp_path / "j.csv"
    path.write_text("q1,q2,q3,q4,q5\n0,0,0,0,0\n0,0,x,0,0\n")
    assert main(["fk", str(path)]) == 2
    assert capsys.readouterr().err.startswith(f"{path}:3: field 'q3': not a number")
    path.write_text("q1,q2,q3,q5\n0,0,0,0\n")
    assert main(["fk", str(path)]) == 2
    assert capsys.readouterr().err.startswith(f"{path}:1: field 'q4': missing column")
    assert main(["fk", str(tmp_path / "missing.csv")]) == 2
    assert str(tmp_path / "missing.csv") in capsys.readouterr().err


def test_bad_arm_toml_exit_2(tmp_path, capsys, poses):
    arm = tmp_path / "arm.toml"
    arm.write_text("name = 'x'\n")
    assert main(["solve", str(poses[1]), "--arm", str(arm)]) == 2
    assert capsys.readouterr().err.startswith(f"{arm}: field 'joint'")


def test_arm_limits_from_toml(tmp_path, poses):
    text = resources.files("ik5r").joinpath("data/seed_arm.toml").read_text()
    # joint 3 limited to [0, 180] deg: elbow-down branches are out of limits
    parts = text.split("[[joint]]")
    parts[3] = parts[3].rstrip() + "\nlimits = [0, 180]\n\n"
    arm = tmp_path / "arm.toml"
    arm.write_text("[[joint]]".join(parts))
    out = tmp_path / "o.csv"
    assert main(["solve", str(poses[1]), "-o", str(out), "--arm", str(arm), "--all"]) == 0
    rows = _read(out)
    assert rows and all(float(r["q3"]) >= -1e-12 for r in rows if r["status"] in ("ok", "singular_elbow"))
    assert any("out_of_limits" in r["status"] for r in rows) or len(rows) < 2 * len(poses[0])


def test_bad_near_is_usage_error(poses):
    with pytest.raises(SystemExit) as info:
        main(["solve", str(poses[1]), "--near", "1,2,3"])
    assert info.value.code == 2


def test_console_script_subprocess(poses, tmp_path):
    exe = shutil.which("ik5r")
    cmd = [exe] if exe else [sys.executable, "-m", "ik5r.tools.cli"]
    _, path = poses
    done = subprocess.run([*cmd, "solve", str(path), "--solver", "float"], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0] == "row,branch,q1,q2,q3,q4,q5,status,residual_cm,residual_rad" and len(lines) == 201
    bad = tmp_path / "bad.csv"
    bad.write_text("px,py,pz,ax,ay,az\n1,2,3,0,0\n")
    done = subprocess.run([*cmd, "solve", str(bad)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert done.stderr.strip() == f"{bad}:2: expected 6 fields, got 5"


def test_verilog_dsp_applies_to_the_pipelined_arch(tmp_path, capsys):
    """--dsp ecp5 with --arch all: the pipelined build with the primitives, the iterative one
    generic; with --arch iterative: one line naming the option, exit 2, nothing written."""
    assert main(["verilog", "-q", "--block", "sqrt", "--arch", "all", "--dsp", "ecp5", "-o", str(tmp_path / "v")]) == 0
    assert sorted(p.name for p in (tmp_path / "v").glob("*.v")) == ["ik5r_sqrt_dspecp5_pipelined.v",
                                                                   "ik5r_sqrt_iterative.v"]
    capsys.readouterr()
    assert main(["verilog", "--block", "sqrt", "--arch", "iterative", "--dsp", "ecp5", "-o", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("--dsp:") and "pipelined" in err[0]
    assert not (tmp_path / "w").exists()


def test_verilog_dsp_of_the_compact_core(tmp_path, capsys):
    """--dsp ecp5 with --block ik --arch compact: the core's limb multiplier on MULT18X18D whose
    input registers (enabled by the pick) are its limb registers, output unregistered: one DSP,
    two with --wide-product; the same latency as the generic core. With --arch all the compact
    core stays generic (the mapping is asked of it by name)."""
    def built(*extra):
        out = tmp_path / "-".join(extra or ("plain",))
        assert main(["verilog", "-q", "--block", "ik", "--config", "q18", *extra, "-o", str(out)]) == 0
        return {p.stem: (p.read_text(), json.loads(p.with_suffix(".json").read_text())) for p in out.glob("*.v")}

    plain, = built("--arch", "compact").values()
    (name, (text, pmap)), = built("--arch", "compact", "--dsp", "ecp5").items()
    assert name == "ik5r_ik_dspecp5_compact" and pmap["latency_cycles"] == plain[1]["latency_cycles"]
    assert text.count("MULT18X18D #(") == 1 and "MULT18X18D" not in plain[0]
    assert '.REG_INPUTA_CLK("CLK0")' in text and '.REG_OUTPUT_CLK("NONE")' in text
    (name, (text, _)), = built("--arch", "compact", "--dsp", "ecp5", "--wide-product").items()
    assert name == "ik5r_ik_dspecp5_wide_product1_compact" and text.count("MULT18X18D #(") == 2
    both = built("--arch", "all", "--dsp", "ecp5")
    assert sorted(both) == ["ik5r_ik_compact", "ik5r_ik_dspecp5_pipelined"]
    capsys.readouterr()


def test_synth_maps_the_compact_core_to_dsps_only_when_asked():
    """``ik5r synth`` on ECP5: the pipelined arch takes the primitives by default, the compact
    core only with --dsp given (the sweep's and the records' compact cores stay generic)."""
    from ik5r.tools.synth import _design
    from ik5r.tools.synth_options import SynthOptions
    from ik5r.tools.design import Design

    core = Design.resolve("ik", "compact", config="q18")
    default = SynthOptions(pnr=False).resolved()
    asked = SynthOptions(pnr=False, dsp="ecp5").resolved()
    assert default.dsp == asked.dsp == "ecp5" and default.resolved().dsp_given is False
    assert asked.resolved().dsp_given is True
    assert _design(core, default)[3]["module"] == "ik5r_ik_compact"
    assert _design(core, asked)[3]["module"] == "ik5r_ik_dspecp5_compact"
    pipelined = Design.resolve("ik", "pipelined", config="q18")
    assert _design(pipelined, default)[3]["module"].startswith("ik5r_ik_dspecp5_")


def test_verilog_rotations_per_stage(tmp_path, capsys):
    """--rotations-per-stage 2: the pipelined module named with it, its latency shorter; with
    --arch iterative: one line naming the option, exit 2, nothing written."""
    assert main(["verilog", "-q", "--block", "sqrt", "--config", "q18", "--rotations-per-stage", "2",
                 "-o", str(tmp_path / "v")]) == 0
    maps = {p.stem: json.loads(p.read_text()) for p in (tmp_path / "v").glob("*.json")}
    assert list(maps) == ["ik5r_sqrt_rotations_per_stage2_pipelined"]
    assert maps["ik5r_sqrt_rotations_per_stage2_pipelined"]["latency_cycles"] == 12
    capsys.readouterr()
    assert main(["verilog", "--block", "sqrt", "--arch", "iterative", "--rotations-per-stage", "2",
                 "-o", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("--rotations-per-stage:") and "pipelined" in err[0]
    assert not (tmp_path / "w").exists()


def test_verilog_poses(tmp_path, capsys):
    """--poses 2: the compact IK core's module named with it, two poses a program length (the
    program's poses per result); asked of the pipelined core: one line, exit 2, nothing written."""
    assert main(["verilog", "-q", "--block", "ik", "--arch", "compact", "--config", "q18", "--poses", "2",
                 "-o", str(tmp_path / "v")]) == 0
    maps = {p.stem: json.loads(p.read_text()) for p in (tmp_path / "v").glob("*.json")}
    assert list(maps) == ["ik5r_ik_poses2_compact"]
    from ik5r.core.fxconfig import constants, load_config
    from ik5r.hdl.sequenced.program import ik_program
    k = constants(load_config("q18"))
    assert maps["ik5r_ik_poses2_compact"]["cycles_per_result"] == len(ik_program(k, poses=2).code) / 2
    capsys.readouterr()
    assert main(["verilog", "--block", "ik", "--arch", "pipelined", "--poses", "2", "-o", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("--poses:") and "compact" in err[0]
    assert not (tmp_path / "w").exists()
