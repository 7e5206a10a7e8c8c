"""The report's ISO 9513 verification section: the class of the verified gauge length, its table, the warnings."""

import json

import pytest

from livedic.dic.strain.iso9513 import classify
from livedic.stream.export.report_verification import (VERIFICATION_KIND, axial_end_fit, load_verification,
                                                       verification_markdown, verification_section)


def _verification(lengths=(200.0, 400.0), scale=10.0, subset=21):
    entries = []
    for length in lengths:
        true = [0.0, 0.01 * length]
        entry = classify(true, [[0.001, -0.001], [true[1] + 0.003, true[1] + 0.005]], length,
                         scale_px_per_mm=scale).as_dict()
        for row, label in zip(entry["steps"], ("rigid 0,0 px", "1 %")):
            row["label"] = label
        entries.append(entry)
    return {"kind": VERIFICATION_KIND, "date": "2026-12-02T14:00:00+00:00", "standard": "ISO 9513:2012 Table 2",
            "settings": {"subset": subset, "scale_px_per_mm": scale, "frames_per_step": 2, "noise": 1.0,
                         "bit_depth": 8, "step_px": 14}, "gauge_lengths": entries}


def test_the_class_of_the_sessions_gauge_length_with_its_table():
    section = verification_section(_verification(), gauge_length_px=400.0, subset=21, scale_px_per_mm=10.0)
    assert section["verified"] and section["class"] == "0.2" and section["l0_px"] == 400.0
    assert section["warnings"] == []
    text = "\n".join(verification_markdown(section))
    assert "## Extensometer verification (ISO 9513)" in text and "class met: **0.2** at L0 400 px = 40 mm" in text
    assert "| 1 % | 4.0000 | 4.0040 | 0.40 | 0.100 | 0.10 | 0.2 |" in text
    assert "2026-12-02" in text and "subset 21 px" in text


@pytest.mark.parametrize("session, warns", [(dict(gauge_length_px=300.0, subset=21, scale_px_per_mm=10.0),
                                             "gauge length 300 px differs"),
                                            (dict(gauge_length_px=400.0, subset=31, scale_px_per_mm=10.0),
                                             "subset 31 px differs"),
                                            (dict(gauge_length_px=400.0, subset=21, scale_px_per_mm=20.0),
                                             "session's scale is 20 px/mm")])
def test_a_session_unlike_the_verification_is_warned(session, warns):
    section = verification_section(_verification(), **session)
    assert any(warns in line for line in section["warnings"]), section["warnings"]
    assert warns in "\n".join(verification_markdown(section))


def test_a_session_with_other_extensometer_ends_than_the_verification_is_warned():
    verification = _verification()
    verification["settings"]["end_fit"] = "band"
    same = verification_section(verification, gauge_length_px=400.0, subset=21, scale_px_per_mm=10.0, end_fit="band")
    assert same["warnings"] == [] and "band ends" in "\n".join(verification_markdown(same))
    other = verification_section(verification, gauge_length_px=400.0, subset=21, scale_px_per_mm=10.0, end_fit="local")
    assert other["warnings"] == ["the session's extensometer ends are local, the verification's band: their noise "
                                 "differs (--extensometer-ends)"]
    # a verification, or a recording, made before the choice existed: local ends
    older = verification_section(_verification(), gauge_length_px=400.0, subset=21, scale_px_per_mm=10.0,
                                 end_fit=axial_end_fit({}))
    assert older["warnings"] == []
    assert axial_end_fit({"extensometer_end_fits": {"axial": "band", "transverse": "local"}}) == "band"


def test_without_verification_the_report_says_so_and_names_the_command():
    section = verification_section(None, gauge_length_px=400.0, subset=21, scale_px_per_mm=10.0)
    assert not section["verified"] and section["class"] is None
    assert "not verified" in section["statement"] and "livedic bench extensometer" in section["statement"]
    assert "not verified" in "\n".join(verification_markdown(section))


def test_bad_verification_files_are_one_line(tmp_path):
    with pytest.raises(ValueError, match="is not a file"):
        load_verification(tmp_path / "missing.json")
    broken = tmp_path / "broken.json"
    broken.write_text("{not json")
    with pytest.raises(ValueError, match="cannot be read as JSON"):
        load_verification(broken)
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"E_GPa": 200}))
    with pytest.raises(ValueError, match="not an extensometer verification"):
        load_verification(other)
    good = tmp_path / "good.json"
    good.write_text(json.dumps(_verification()))
    assert load_verification(good)["gauge_lengths"][1]["l0_px"] == 400.0
