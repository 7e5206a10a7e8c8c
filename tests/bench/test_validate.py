"""``livedic bench validate``: the quick synthetic run finds no wrong-but-ok point and says so."""

from livedic.bench.validate import run_validate_benchmark


def test_quick_validation_has_no_wrong_ok_point_and_checks_the_zncc_gate():
    lines = []
    code = run_validate_benchmark(quick=True, log=lines.append)
    text = "\n".join(lines)
    assert code == 0, text
    assert "PASS: no point more than 0.5 px off is reported ok" in text
    assert "is below every correct point" in text
    rows = [line for line in lines if " r 32 " in line]
    assert len(rows) == 4 * 2 * 3            # generators x shifts x methods (quick)
    assert all(line.split()[-2] == "0" for line in rows)
