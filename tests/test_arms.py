"""Your arm in the fixed-point path (issue 26), the cheap part: the shipped arms against their
sources' poses, ``ik5r arms``, formats that hold the arm (``ik5r config --arm``, refusal of an arm
too big for a config by every fixed-point command), the arm in the C header and the records, and
C == scalar model == vectorised model with the tool-point error floor on every shipped arm.
The cocotb runs of the cores are in tests/test_cocotb_arms.py."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ik5r.core import reference as ref
from ik5r.core.arm import load_arm, shipped_arm_names
from ik5r.core.armfit import integer_bits_for, length_bounds
from ik5r.core.chain import closed_form_arm
from ik5r.core.errors import InputError
from ik5r.core.fxconfig import Constants, load_config
from ik5r.tools.cli import main

#: The shipped arms of the closed-form family other than the arm of record.
REAL_ARMS = ("scorbot-er4u", "youbot-arm", "al5d", "px150")
FAMILY = tuple(n for n in shipped_arm_names() if closed_form_arm(n) is not None)

#: q = 0 of each file and the tool point its source gives for that configuration (mm; see the
#: comment at the top of each file): Kutzer's ScorBot zero configuration, the youBot's candle,
#: Mazurov's AL5D dimensions stretched out, Interbotix's home pose M of the PincherX 150.
DOCUMENTED = {
    "scorbot-er4u": (16 + 221 + 221 + 145.125, 0.0, 349.0),
    "youbot-arm": (33.0, 0.0, 147 + 155 + 135 + 218.0),
    "al5d": (146.05 + 187.325 + 100.0, 0.0, 67.31),
    "px150": (358.575, 0.0, 254.57),
}


def test_four_real_arms_shipped_besides_the_arm_of_record():
    assert set(REAL_ARMS) <= set(FAMILY) and "hu-5r" in FAMILY


@pytest.mark.parametrize("name", REAL_ARMS)
def test_arm_matches_its_sources_pose(name):
    arm = load_arm(name)
    p, _, _, a = ref.fk(arm, np.zeros((1, 5)))
    np.testing.assert_allclose(p[0] * 10.0, DOCUMENTED[name], atol=1e-9)
    # Every file cites where its numbers come from.
    assert "\n# Source: " in open(arm.source).read()


def test_px150_joints_are_interbotix_joints():
    """The PincherX file's offsets make q the arm's own reading: the elbow joint at the home pose's
    screw axis (0.05, 0.25457) m and the wrist at (0.2, 0.25457) m, from Interbotix's Slist (the
    shoulder at z = 0.10457 m: 150 mm below)."""
    arm = load_arm("px150")
    lengths = np.array(arm.a) * 10.0
    angles = np.cumsum(np.array(arm.theta_offset)[1:3])
    elbow = lengths[1] * np.array([np.cos(angles[0]), -np.sin(angles[0])])
    wrist = elbow + lengths[2] * np.array([np.cos(angles[1]), -np.sin(angles[1])])
    np.testing.assert_allclose(elbow, (50.0, 150.0), atol=1e-9)
    np.testing.assert_allclose(wrist, (200.0, 150.0), atol=1e-9)


def test_arms_lists_reach_and_source(capsys):
    assert main(["arms"]) == 0
    out = capsys.readouterr().out
    for name in (*REAL_ARMS, "hu-5r"):
        line = next(ln for ln in out.splitlines() if ln.startswith(name + " "))
        assert "closed form" in line and f"{load_arm(name).reach:.2f}" in line
    assert "Source: M. Kutzer" in out and "Source: O. Mazurov" in out and "Source: Interbotix" in out


def test_config_for_the_arm_of_record_is_the_shipped_one(tmp_path, capsys):
    """``ik5r config`` writes by the shipped configs' rule: for hu-5r at 32 bits with 6 internal
    guard bits it is q32w, number for number."""
    out = tmp_path / "q32w.toml"
    assert main(["config", "--arm", "hu-5r", "--width", "32", "--internal-guard-bits", "6", "-o", str(out)]) == 0
    written, shipped = load_config(out), load_config("q32w")
    assert written.to_toml() == shipped.to_toml()
    assert 'for the arm "hu-5r"' in out.read_text()


def _big_arm(tmp_path):
    text = open(load_arm("scorbot-er4u").source).read().replace('name = "scorbot-er4u"', 'name = "big"')
    path = tmp_path / "big.toml"
    path.write_text(text.replace("a = 221\n", "a = 700\n"))
    return path


def test_config_for_a_big_arm_holds_it(tmp_path):
    big = load_arm(_big_arm(tmp_path))
    with pytest.raises(InputError, match="does not fit config q32w"):
        Constants(load_config("q32w"), big)
    out = tmp_path / "big32.toml"
    assert main(["config", "--arm", str(_big_arm(tmp_path)), "--width", "32", "-o", str(out)]) == 0
    cfg = load_config(out)
    assert cfg.width - cfg.frac_length == integer_bits_for(big) == 10
    Constants(cfg, big)     # holds it: no error


@pytest.mark.parametrize("argv", [
    ["verilog", "--block", "ik", "-o", "{tmp}/v"],
    ["sim", "--block", "ik", "--arch", "compact", "--vectors", "1"],
    ["synth", "--block", "ik", "--arch", "compact", "--no-pnr", "--cache", "{tmp}/s"],
    ["firmware", "--vectors", "1"],
    ["solve", "{tmp}/p.csv", "--solver", "fixed"],
    ["solve", "{tmp}/p.csv", "--solver", "c"],
    ["solve", "{tmp}/p.csv", "--solver", "rv32"],
    ["report", "--hdl", "-o", "{tmp}/r"],
], ids=lambda argv: "-".join(argv[:2]))
def test_arm_too_big_refused_in_one_line(argv, tmp_path, capsys):
    (tmp_path / "p.csv").write_text("px,py,pz,ax,ay,az\n30,5,20,1,0,0\n")
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv] + ["--arm", str(_big_arm(tmp_path))]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "arm big does not fit config q32w" in err[0]
    assert "reaches 156.1 cm" in err[0] and "no width up to 32 fits" in err[0]
    assert not (tmp_path / "v").exists() and not (tmp_path / "s").exists()


def test_bounds_cover_random_reachable_poses():
    """The bounds armfit checks hold every reachable pose: the tool point and the wrist centre of
    random joints of each shipped arm stay within them."""
    rng = np.random.default_rng(3)
    for name in FAMILY:
        arm = load_arm(name)
        q = rng.uniform(-np.pi, np.pi, size=(5000, 5))
        p, _, _, a = ref.fk(arm, q)
        bounds = {quantity.split(" (")[0]: b for quantity, b, _ in length_bounds(arm)}
        assert np.abs(p[:, :2]).max() <= bounds["tool point x, y"]
        assert np.abs(p[:, 2]).max() <= bounds["tool point z"]


def test_c_header_names_the_arm():
    from ik5r.firmware_model.codegen import generate_header

    arm = load_arm("al5d")
    text = generate_header(Constants(load_config("q32w"), arm))
    assert '#define IK5R_ARM_NAME "al5d"' in text and f'"{arm.dh_sha256()}"' in text


def test_record_names_carry_the_arm():
    from ik5r.tools.results import _record_name

    r = {"module": "ik5r_ik_compact", "config": "q32w", "target": "ecp5", "device": "25k"}
    assert _record_name(r) == "ik5r_ik_compact_q32w_ecp5-25k.json"
    assert _record_name(dict(r, arm="hu-5r")) == "ik5r_ik_compact_q32w_ecp5-25k.json"
    assert _record_name(dict(r, arm="al5d")) == "ik5r_ik_compact_q32w_arm-al5d_ecp5-25k.json"


@pytest.mark.parametrize("name", FAMILY)
def test_software_bit_exact_and_error_floor(name):
    """C == scalar model == vectorised model on every output field (random and directed poses),
    and the tool-point error against float64 within 5e-9 x the arm's reach, at q32w."""
    from ik5r.tools.arm_accuracy import ERROR_FLOOR_PER_REACH, measure

    r = measure(load_arm(name), load_config("q32w"), poses=4000)
    assert r["software_differing_fields"] == 0, json.dumps(r["software_agreement"])
    assert r["software_agreement"]["poses"] > 500
    assert r["position_err_max_cm"] <= ERROR_FLOOR_PER_REACH * r["reach_cm"], r


@pytest.mark.parametrize("solver", ["fixed", "c"])
def test_fixed_solvers_flag_out_of_limits_and_prefer_in_limit_branches(solver, tmp_path):
    """The SCORBOT's elbow stops at +-130 deg: a pose of q3 = 150 deg has no in-limit branch of
    that elbow angle; ``solve --solver fixed|c`` marks the answer out_of_limits. A pose whose first
    branch (elbow up) needs the wrist pitch at -140 deg gets its in-limit elbow-down branch."""
    import csv

    arm = load_arm("scorbot-er4u")
    q = np.array([[0.2, 0.3, np.radians(150), 0.2, 0.1], [0.2, 0.3, np.radians(-100), np.radians(-40), 0.1]])
    p, n, o, a = ref.fk(arm, q)
    rows = ["px,py,pz,nx,ny,nz,ox,oy,oz,ax,ay,az"] + [
        ",".join(repr(float(v)) for v in (*p[i], *n[i], *o[i], *a[i])) for i in range(2)]
    (tmp_path / "poses.csv").write_text("\n".join(rows) + "\n")
    out = tmp_path / "out.csv"
    assert main(["solve", str(tmp_path / "poses.csv"), "--solver", solver, "--arm", "scorbot-er4u",
                 "-o", str(out)]) == 0
    got = list(csv.DictReader(open(out)))
    assert "out_of_limits" in got[0]["status"]
    assert got[1]["status"] == "ok" and got[1]["branch"] == "1"
    np.testing.assert_allclose([float(got[1][f"q{j}"]) for j in range(1, 6)], q[1], atol=1e-6)


def test_build_id_hashes_do_not_depend_on_where_the_arm_file_lives(tmp_path):
    """The board's ID-frame arm hash and the peripheral's ARM_HASH of an arm read by name, by
    its path, and from a copy elsewhere are equal: a board built in one clone is accepted by the
    host of another."""
    import shutil

    from ik5r.core import link, regmap
    from ik5r.core.arm import load_arm
    from ik5r.core.fxconfig import constants, load_config

    by_name = load_arm("al5d")
    copy = tmp_path / "elsewhere" / "al5d.toml"
    copy.parent.mkdir()
    shutil.copy(by_name.source, copy)
    arms = [by_name, load_arm(str(copy))]
    assert str(arms[0].source) != str(arms[1].source)
    ks = [constants(load_config("q32w"), arm) for arm in arms]
    assert link.arm_hash(ks[0]) == link.arm_hash(ks[1])
    ids = [regmap.id_values(k, "1.2.3", "compact", 1)["ARM_HASH"] for k in ks]
    assert ids[0] == ids[1]
    assert link.arm_hash(constants(load_config("q32w"), load_arm("px150"))) != link.arm_hash(ks[0])


def test_arm_of_record_by_name_is_the_default_design_point():
    """``--arm hu-5r`` builds what no ``--arm`` builds (the records of the arm of record are
    matched against the default design point, ``ik5r.tools.results``)."""
    from ik5r.tools.design import Design

    default = Design.resolve("ik", "compact", config="q18")
    named = Design.resolve("ik", "compact", config="q18", arm="hu-5r")
    assert named.constants == default.constants
    assert named.verilog()[0] == default.verilog()[0]
