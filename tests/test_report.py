"""The quantisation report (``ik5r report``) on a small run: files, JSON figures, HTML links."""

from __future__ import annotations

import argparse
import json
import re

import pytest

from ik5r.commands import report as report_cmd
from ik5r.report import Section, build_report, summary_text
from ik5r.report.quantisation import JOINTS, SIN_Q3_BINS

N = 20_000


def _strict_json(path):
    def no_constant(name):
        raise ValueError(f"non-standard JSON constant {name}")
    return json.loads(path.read_text(), parse_constant=no_constant)


@pytest.fixture(scope="module")
def q32_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("report_q32")
    parser = argparse.ArgumentParser()
    report_cmd.register(parser.add_subparsers())
    args = parser.parse_args(["report", "--vectors", str(N), "--config", "q32", "--seed", "3",
                              "--no-progress", "-o", str(out)])
    assert args.run(args) == 0
    return out, _strict_json(out / "report.json")


def test_files_and_meta(q32_run):
    out, doc = q32_run
    assert (out / "index.html").is_file() and (out / "report.json").is_file()
    meta = doc["meta"]
    assert meta["config"] == "q32" and meta["vectors"] == N and meta["seed"] == 3
    assert meta["arm"] == "hu-5r" and meta["total_s"] > 0
    assert list(doc["sections"]) == ["overview", "task_space", "joint_error", "conditioning", "status"]
    for section in doc["sections"].values():
        assert section["title"] and isinstance(section["data"], dict)
    ov = doc["sections"]["overview"]["data"]
    assert ov["config"]["name"] == "q32" and ov["vectors"] == N
    assert sum(ov["branches"]["counts"]) == N
    assert ov["branches"]["max_match_rad"] < 1e-6   # the matched float64 branch is q itself
    assert ov["timing"]["fixed_solver_s"] > 0


def test_html_references_existing_pngs(q32_run):
    out, _ = q32_run
    page = (out / "index.html").read_text()
    images = re.findall(r'<img src="([^"]+)"', page)
    assert len(images) >= 5
    for name in images:
        assert "/" not in name and name.endswith(".png")
        assert (out / name).is_file() and (out / name).stat().st_size > 1000
    for title in ("Task-space error", "Joint-space error", "conditioning", "Status counts"):
        assert title in page
    assert "<table>" in page


def _check_stats(stats):
    assert stats["max"] >= stats["rms"] >= 0
    assert stats["max"] >= stats["mean"] >= 0
    for p in ("p50", "p90", "p99", "p99.9", "p99.99"):
        assert 0 <= stats[p] <= stats["max"]
    assert stats["p50"] <= stats["p90"] <= stats["p99"] <= stats["p99.9"] <= stats["p99.99"]


def test_task_space_figures(q32_run):
    _, doc = q32_run
    ts = doc["sections"]["task_space"]["data"]
    for solver in ("fixed", "float32", "float64"):
        _check_stats(ts[solver]["position_cm"])
        _check_stats(ts[solver]["approach_rad"])
    fixed, f32 = ts["fixed"]["position_cm"], ts["float32"]["position_cm"]
    assert fixed["max"] <= 1e-5                       # q32: well below a tenth of a micrometre
    assert fixed["max"] < f32["max"] and fixed["rms"] < f32["rms"]   # the floor: fixed beats float32
    assert ts["fixed_beats_float32"] is True
    ratio = ts["ratio_fixed_over_float32"]
    assert ratio["position_max"] == pytest.approx(fixed["max"] / f32["max"])
    assert ratio["position_rms"] == pytest.approx(fixed["rms"] / f32["rms"])
    assert ratio["position_max"] < 1 and ratio["position_rms"] < 1
    flagged = ts["fixed_flagged"]
    assert 0 <= flagged["count"] <= N // 1000
    assert flagged["unflagged_position_cm"]["max"] <= fixed["max"]


def test_joint_figures(q32_run):
    _, doc = q32_run
    je = doc["sections"]["joint_error"]["data"]
    lsb = je["angle_lsb_rad"]
    assert lsb == 2.0**-29
    counts = [je["bins"][key]["count"] for key in SIN_Q3_BINS]
    assert counts[0] == N and counts == sorted(counts, reverse=True) and counts[-1] > 0
    assert 0 <= je["near_axis_count"] < N // 100 and je["axis_radius_cm"] > 0
    for comp in ("fixed_vs_exact", "fixed_vs_quantised", "float32_vs_exact", "float32_vs_quantised",
                 "input_effect", "fixed_vs_exact_off_axis", "float32_vs_exact_off_axis"):
        for key in SIN_Q3_BINS:
            for j in JOINTS:
                e = je[comp][key][j]
                assert e["max_rad"] >= e["rms_rad"] >= 0
                assert e["max_lsb"] == pytest.approx(e["max_rad"] / lsb)
                assert e["rms_lsb"] == pytest.approx(e["rms_rad"] / lsb)
    # Narrower |sin q3| bins never have larger maxima; q1 (no division by sin q3) is about one LSB.
    for comp in ("fixed_vs_exact", "fixed_vs_quantised", "fixed_vs_exact_off_axis"):
        for j in JOINTS:
            maxima = [je[comp][key][j]["max_rad"] for key in SIN_Q3_BINS]
            assert maxima == sorted(maxima, reverse=True)
    assert je["fixed_vs_quantised"]["all"]["q1"]["max_lsb"] < 4
    # The joint floor's verdict is the largest own error in its bin; q32 (no internal guard bits)
    # misses it whenever a pose comes close enough to the singular elbow, which is what the
    # default config q32w is for (tests/test_internal_format.py holds q32w to it).
    floor = je["floor"]
    worst = max(je["fixed_vs_quantised"]["sin_q3_ge_1e-3"][j]["max_rad"] for j in JOINTS)
    assert floor["max_rad"] == worst and floor["met"] == (worst <= floor["bound_rad"] == 1e-6)


def test_conditioning_explains_input_effect(q32_run):
    _, doc = q32_run
    c = doc["sections"]["conditioning"]["data"]
    assert c["lsb"]["angle_rad"] == 2.0**-29 and c["lsb"]["length_cm"] == 2.0**-24
    for key, b in c["bins"].items():
        if SIN_Q3_BINS[key] == 0:
            continue
        assert b["bound_q3_rad"] >= b["bound_q2_rad"] > 0
        # The measured input effect stays within the first-order bound of its bin.
        assert b["measured_input_effect_max_rad"]["q2"] <= b["bound_q2_rad"]
        assert b["measured_input_effect_max_rad"]["q3"] <= b["bound_q3_rad"]
        # The solver's own error is the same 1/|sin q3| law with a few length LSB of internal rounding.
        own = b["measured_fixed_own_max_rad"]
        if SIN_Q3_BINS[key] >= 1e-2:
            assert own["q2"] <= 5 * b["bound_q2_rad"] and own["q3"] <= 5 * b["bound_q3_rad"]
    for joint, used in c["max_fraction_of_per_pose_bound_used"].items():
        assert 0 < used <= 1.05, joint


def test_status_counts(q32_run):
    _, doc = q32_run
    s = doc["sections"]["status"]["data"]
    assert sum(s["fixed"].values()) == N and sum(s["float64"].values()) == N
    assert s["fixed"].get("ok", 0) > 0.99 * N
    assert s["input_words_saturated"] == 0
    assert s["fixed_not_ok"] <= N // 1000


def test_build_report_api_and_extra_section(tmp_path):
    extra = Section("bit_accuracy", "Bit accuracy", "<p>placeholder</p>", {"mismatches": 0})
    doc, text = build_report(tmp_path, vectors=2_000, config="q18", seed=5, progress=False,
                             extra_sections=[extra])
    assert doc["sections"]["bit_accuracy"]["data"] == {"mismatches": 0}
    assert "Bit accuracy" in (tmp_path / "index.html").read_text()
    assert "q18" in text and "fixed beats float32" in text
    fig = {**doc["sections"]["overview"]["data"], **{k: doc["sections"][k]["data"]
                                                     for k in ("joint_error", "task_space")},
           "status": doc["sections"]["status"]["data"]}
    assert summary_text(fig).splitlines()[0] == text.splitlines()[0]
