"""``livedic report``'s files for each curve shape: the new keys, the old ones unchanged, the plot's marks.

The curves are the analytic ones of ``tests.dic.tensile.test_yielding.py`` (no noise): the report
is a view of ``tensile_properties``, so what is checked here is what a reader of report.json and
report.md gets, and that the plot draws the yield marks.
"""

import io
import json

import numpy as np
import pytest

from livedic.dic.tensile.properties import tensile_properties
from livedic.stream.export.report import PROPERTY_KEYS, report_json, report_markdown
from livedic.stream.stages.stress import plot_stress_strain, stress_strain_table
from tests.dic.tensile.test_yielding import continuous, perfectly_plastic, upper_yield_point

SPECIMEN = {"area_mm2": 20.0, "gauge_length_px": 400.0}
SOURCE = {"recording": "r.mcap", "truncated": False, "load": "csv:f.csv", "load_offset_s": 0.0, "frames": 1,
          "frames_with_force": 1, "strain": "", "generated_at": "now"}
OLD_KEYS = ("E_GPa", "Rp02_MPa", "Rm_MPa", "Ag_percent", "A_percent")


def _report(curve):
    return report_json(tensile_properties(*curve), SPECIMEN, SOURCE)


def test_upper_yield_point_report_has_reh_rel_ae_with_methods():
    report = _report(upper_yield_point())
    json.dumps(report, allow_nan=False)
    assert PROPERTY_KEYS[:5] == OLD_KEYS
    assert report["curve_shape"]["value"] == "upper_yield_point"
    assert report["ReH_MPa"]["value"] == pytest.approx(330.0)
    assert report["ReL_MPa"]["value"] == pytest.approx(300.0)
    assert report["Ae_percent"]["value"] == pytest.approx(2.0, abs=0.05)
    assert "3.10.2.1" in report["ReH_MPa"]["method"] and "3.10.2.2" in report["ReL_MPa"]["method"]
    text = report_markdown(report, "plot.png", "r.mcap")
    assert "| ReH | 330 | MPa |" in text and "| ReL | 300 | MPa |" in text and "| Ae |" in text
    assert "upper yield point" in text


def test_perfectly_plastic_report_says_why_rm_and_ag_are_missing():
    report = _report(perfectly_plastic())
    assert report["curve_shape"]["value"] == "plateau"
    assert report["Rp02_MPa"]["value"] == pytest.approx(300.0)
    for key in ("Rm_MPa", "Ag_percent"):
        assert report[key]["value"] is None and "3.9.2 Note 1" in report[key]["reason"]
    assert report["Ae_percent"]["value"] == pytest.approx(5.0, abs=0.1)
    text = report_markdown(report, "plot.png", "r.mcap")
    assert "| Rm | n/a | MPa |" in text and "leaves the maximum force Fm undefined" in text
    assert "Ag and Agt not read: the maximum force is undefined" in text and "Ag and Agt read" not in text


def test_continuous_report_keeps_the_old_readings_and_says_there_is_no_yield_point():
    report = _report(continuous())
    assert report["curve_shape"]["value"] == "continuous"
    assert all(report[key]["value"] is not None for key in OLD_KEYS[:4])
    assert all(report[key]["value"] is None and "no yield phenomenon" in report[key]["reason"]
               for key in ("ReH_MPa", "ReL_MPa", "Ae_percent"))


def test_the_plot_marks_reh_rel_and_ae(monkeypatch):
    from matplotlib.figure import Figure
    strain, stress = upper_yield_point()
    frames = np.arange(strain.size)
    table = stress_strain_table(frames, frames * 0.1, stress * SPECIMEN["area_mm2"], strain, SPECIMEN["area_mm2"])
    properties = tensile_properties(table.eng_strain, table.eng_stress_MPa)
    drawn = []
    original = Figure.savefig

    def keep_labels(figure, *args, **kwargs):
        drawn.extend(text.get_text() for text in figure.axes[0].get_legend().get_texts())
        return original(figure, *args, **kwargs)
    monkeypatch.setattr(Figure, "savefig", keep_labels)
    plot_stress_strain(io.BytesIO(), table, title="t", properties=properties)
    labels = " | ".join(drawn)
    assert "ReH = 330.0 MPa" in labels and "ReL = 300.0 MPa" in labels and "Ae = " in labels
