"""``livedic bench paper``: plumbing and sanity of the paper reproduction (no timing asserted).

One run of the tiny configuration (every stage, figure and check, a few dozen
points each) feeds all the checks below.
"""

import json
import os

import numpy as np
import pytest

from livedic.bench.paper import runs
from livedic.bench.paper import PaperConfig, run_paper_benchmark

FIGURES = ["fig09_success.png", "fig09_success_noise.png", "fig10_cost.png", "fig_radius.png", "fig11_subpixel.png",
           "fig11_subpixel_noise.png", "table1_time.png", "fig07_fitting_distance.png",
           "fig07_fitting_distance_noise.png", "fig12_u_field.png", "fig12_u_field_noise.png"]
TABLES = ["fig09_success.csv", "fig10_cost.csv", "fig_radius.csv", "fig11_subpixel.csv", "fig11_icgn_noise_check.csv",
          "table1_time.csv", "fig07_fitting_distance.csv", "fig12_u_field.csv", "results.json", "report.md"]


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("paper")
    lines = []
    code = run_paper_benchmark(str(out), config=PaperConfig.tiny(), log=lines.append)
    with open(out / "results.json") as handle:
        results = json.load(handle)
    report = (out / "report.md").read_text()
    return dict(out=out, code=code, lines=lines, results=results, report=report)


def test_every_stage_runs_without_error(tiny_run):
    assert tiny_run["results"]["errors"] == {}, tiny_run["results"]["errors"]
    assert tiny_run["code"] == 0
    assert any(line.startswith("done in") for line in tiny_run["lines"])


def test_every_figure_and_raw_table_is_written(tiny_run):
    for name in FIGURES + TABLES:
        path = tiny_run["out"] / name
        assert path.is_file() and path.stat().st_size > 0, name
    for name in FIGURES:
        with open(tiny_run["out"] / name, "rb") as handle:
            assert handle.read(8) == b"\x89PNG\r\n\x1a\n", name


def test_report_embeds_every_figure_and_has_every_section(tiny_run):
    report = tiny_run["report"]
    for name in FIGURES:
        assert f"]({name})" in report, name
    for heading in ("## Accuracy checks", "## Setup", "## Fig 9", "## Fig 10", "## Fig 11", "## Table 1", "## Fig 7",
                    "## Fig 12", "## Where our numbers differ from the paper and why"):
        assert heading in report, heading
    assert f"{os.cpu_count()} CPU cores" in report
    assert "numba" in report


def test_accuracy_checks_are_all_evaluated(tiny_run):
    checks = tiny_run["results"]["checks"]
    assert len(checks) == 9   # 5 targets of the issue, IC-GN on exact images (2), rounding-noise check, radius study
    assert all(c["result"] in ("PASS", "FAIL") for c in checks), checks
    for c in checks:
        assert f"**{c['result']}** {c['name']}" in tiny_run["report"]


def test_integer_search_numbers_are_sane(tiny_run):
    results = tiny_run["results"]
    cfg = PaperConfig.tiny()
    box = (2 * cfg.search_radius + 1) ** 2
    for key in ("integer_clean", "integer_noisy"):
        rows = results[key]["rows"]
        assert {r["method"] for r in rows} == {"exhaustive", "coarse-fine", "pso", "wso", "improved-wso"}
        for r in rows:
            assert r["n"] == results[key]["points_per_pair"] * cfg.int_patterns
            assert 0.0 <= r["success_pct"] <= 100.0 and 0.0 <= r["truth_pct"] <= 100.0
            assert 0 < r["evaluations"] <= box and r["calls"] >= r["evaluations"]
        exhaustive = [r for r in rows if r["method"] == "exhaustive"]
        assert all(r["evaluations"] == box for r in exhaustive)
        # Exact translations of a speckle pattern: the ZNCC argmax is the true integer shift.
        assert all(r["truth_pct"] == 100.0 for r in exhaustive)
    clean = [r for r in results["integer_clean"]["rows"] if r["method"] == "improved-wso"]
    assert all(r["success_pct"] == 100.0 for r in clean), [(r["displacement"], r["success_pct"]) for r in clean]
    cost = results["integer_clean"]["cost"]
    assert cost["pso"]["time_vs_pso"] == pytest.approx(1.0)
    assert cost["coarse-fine"]["time_vs_coarse-fine"] == pytest.approx(1.0)


def test_subpixel_numbers_are_sane(tiny_run):
    results = tiny_run["results"]
    clean = {(r["method"], r["displacement"]): r for r in results["subpixel_clean"]["rows"]}
    assert {m for m, _ in clean} == set(runs.SUBPIXELS)
    for (method, s), r in clean.items():
        assert r["n"] > 0 and abs(r["mean_u"]) < 0.15, (method, s, r)
    icgn = [r for (m, _), r in clean.items() if m == "icgn"]
    assert max(abs(r["mean_u"]) for r in icgn) < 0.002
    assert max(r["sd_u"] for r in icgn) < 0.01          # 8-bit rounding noise: ~0.004 px
    exact = [r for r in results["subpixel_exact"]["rows"] if r["method"] == "icgn"]
    assert max(abs(r["mean_u"]) for r in exact) < 0.0005
    assert max(r["sd_u"] for r in exact) < 0.001        # the method's own error: ~0.0001 px
    # IC-GN2 on translations: no curvature to fit, so the same fixed point up to its larger noise
    # (8-bit rounding: SD ~0.008 px against IC-GN's ~0.004; exact images ~0.0002 px)
    icgn2 = [r for (m, _), r in clean.items() if m == "icgn2"]
    assert max(abs(r["mean_u"]) for r in icgn2) < 0.003
    assert max(r["sd_u"] for r in icgn2) < 0.02
    exact2 = [r for r in results["subpixel_exact"]["rows"] if r["method"] == "icgn2"]
    assert max(abs(r["mean_u"]) for r in exact2) < 0.0005
    assert max(r["sd_u"] for r in exact2) < 0.001
    rounding = results["subpixel_clean"]["icgn_noise"]
    assert 0.7 < rounding["ratio_first_order"] < 1.3, rounding
    isf = [r for (m, _), r in clean.items() if m == "improved-surface-fit"]
    assert max(abs(r["mean_u"]) for r in isf) < 0.01
    noise = results["subpixel_noisy"]["icgn_noise"]
    assert 0.5 < noise["ratio"] < 2.0, noise
    fit = results["subpixel_clean"]["fit_rows"]
    assert {r["spacing"] for r in fit} == set(PaperConfig.tiny().fit_spacings)
    assert {r["displacement"] for r in fit} == set(PaperConfig.tiny().fit_displacements)


def test_table1_and_field(tiny_run):
    results = tiny_run["results"]
    stage = results["subpixel_clean"]["stage_time_s"]
    whole = results["measure_timing"]["methods"]
    assert set(stage) == set(runs.SUBPIXELS) == set(whole)
    assert all(t > 0 for t in stage.values()) and all(w["time_s"] > 0 for w in whole.values())
    field = results["field_clean"]
    side = len(field["axis"])
    for method, u in field["u"].items():
        u = np.array(u, dtype=float)
        assert u.shape == (side * side,)
        assert np.nanmax(np.abs(u - 0.5)) < 0.2, method


def test_icgn_noise_prediction_of_a_ramp():
    # f = 3 x: f_x = 3 on every pixel, f_y = 0 -> sqrt(2) sigma / (3 sqrt(n)).
    x = np.arange(40, dtype=float)
    ramp = np.tile(3.0 * x, (40, 1)) + np.random.default_rng(0).normal(0, 1e-9, (40, 40))
    translation, _ = runs.icgn_noise_prediction(ramp, np.array([[20.0, 20.0]]), 5, 2.0)
    assert translation[0] == pytest.approx(np.sqrt(2) * 2.0 / (3.0 * 11), rel=1e-6)


def test_grid_points_and_seeds_are_deterministic():
    points = runs.grid_points(10, 50, 20)
    assert points.tolist() == [[10, 10], [30, 10], [50, 10], [10, 30], [30, 30], [50, 30], [10, 50], [30, 50],
                               [50, 50]]
    assert runs.noise_seed(0, "sub", 1, 0.5) == runs.noise_seed(0, "sub", 1, 0.5)
    assert runs.noise_seed(0, "sub", 1, 0.5) != runs.noise_seed(0, "sub", 2, 0.5)


def test_a_failing_method_is_recorded_and_skipped():
    messages = []
    guard = runs.Guard(messages.append)

    def broken():
        raise RuntimeError("boom")

    result, seconds = guard.call("pso", broken)
    assert result is None and np.isnan(seconds)
    assert not guard.ok("pso") and "boom" in guard.failed["pso"]
    assert guard.call("pso", lambda: 1)[0] is None  # skipped from then on
    result, seconds = guard.call("icgn", lambda: 42)
    assert result == 42 and seconds >= 0
    assert len(messages) == 1
