"""The machine's force in a live session (``--load``): force and stress per frame, in the summary.

The simulated test's own law (``--load synthetic``: E 200 GPa, yield 800 MPa, perfectly plastic by
default) and a force file with a known ramp give exact values at the frames' times.
"""

import json

import pytest

from livedic.stream.session.config import DEFAULT_STATIC_FRAMES
from livedic.stream.cli import main
from tests.stream.conftest import refused_run

SOURCE = "synthetic:tensile?size=384x512&frames=40&pace=0"


def run_with(tmp_path, *extra):
    summary = tmp_path / "summary.json"
    code = main(["run", "--source", SOURCE, "--viewer", "none", "--no-record", "--progress", "off",
                 "--summary-json", str(summary), *extra])
    assert code == 0
    return json.loads(summary.read_text())["force"]


def test_the_simulated_law_gives_its_yield_stress(tmp_path):
    force = run_with(tmp_path, "--load", "synthetic")
    assert force["area_mm2"] == pytest.approx(0.4 * 384 / 10 * 2)        # the simulator's own A0
    assert force["max_stress_MPa"] == pytest.approx(800.0, rel=1e-9)    # perfectly plastic at 200 GPa x 0.004
    assert force["frames_without_force"] == 0 and force["frames"] == 40 + DEFAULT_STATIC_FRAMES


def test_a_force_file_is_read_at_the_frame_times(tmp_path):
    ramp = tmp_path / "force.csv"
    ramp.write_text("time_s,force_N\n" + "".join(f"{0.1 * k:.1f},{1000.0 * 0.1 * k}\n" for k in range(9)))
    # the frames' times are what this is about: the test's 40 frames only, no static ones before
    force = run_with(tmp_path, "--load", f"csv:{ramp}", "--area", "20", "--static-frames", "0")
    # frames every 1/50 s: the file covers 0..0.8 s, frames 0..39 run to 0.78 s
    assert force["final_force_N"] == pytest.approx(1000.0 * 39 / 50, rel=1e-9)
    assert force["final_stress_MPa"] == pytest.approx(1000.0 * 39 / 50 / 20, rel=1e-9)
    short = tmp_path / "short.csv"
    short.write_text("time_s,force_N\n0,0\n0.4,400\n")
    force = run_with(tmp_path, "--load", f"csv:{short}", "--static-frames", "0")
    assert force["frames_without_force"] == 19                          # after 0.4 s: NaN, never extrapolated
    assert force["final_force_N"] is None and force["max_stress_MPa"] is None


@pytest.mark.parametrize("extra, message", [
    (["--load", "csv:/nonexistent.csv"], "load file /nonexistent.csv"),
    (["--area", "10"], "without --load"),
    (["--load", "synthetic", "--area", "-1"], "--area"),
])
def test_bad_load_options_are_one_line_exit_2_and_leave_no_file(tmp_path, extra, message):
    assert message in refused_run(tmp_path, extra)


def test_recorded_force_gives_the_simulators_properties(tmp_path):
    """run --load synthetic records the force on /machine/force; report then needs no force file.
    The simulator's law with hardening 0.5: E 200 GPa, Rp0.2 816 MPa, Rm 1200 MPa exactly; the issue's
    bound: within 1 % (E within 2 %), through the axial extensometer's strain."""
    source = "synthetic:tensile?size=384x512&frames=300&pace=0&hardening=0.5"
    record = tmp_path / "test.mcap"
    assert main(["run", "--source", source, "--load", "synthetic", "--record", str(record), "--viewer", "none",
                 "--progress", "off", "--gauge-length", "200"]) == 0
    out = tmp_path / "report"
    assert main(["report", str(record), "-o", str(out)]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["E_GPa"]["value"] == pytest.approx(200.0, rel=0.02)
    assert report["Rp02_MPa"]["value"] == pytest.approx(816.0, rel=0.01)
    assert report["Rm_MPa"]["value"] == pytest.approx(1200.0, rel=0.01)
    assert report["A_percent"]["value"] is None and report["A_percent"]["reason"]    # no fracture in this test
