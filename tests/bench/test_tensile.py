"""``livedic bench tensile --quick``: the properties it reports are within the issue's bounds of the law.

Quick mode: 512 x 512, 150 frames, axial extensometer 200 px (measured: E 0.986, Rp0.2 1.000, Rm 0.998 of
the law; Ag and A 0.999 of the same methods on the exact strain). Accuracy bounds only.
"""

import csv

from livedic.bench.cli import main


def test_quick_tensile_benchmark_recovers_the_law(tmp_path, capsys):
    assert main(["bench", "tensile", "--quick", "-o", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert out.count(": MET") == 3 and "NOT MET" not in out
    with open(tmp_path / "tensile.csv", newline="") as handle:
        rows = {row["property"]: row for row in csv.DictReader(handle)}
    assert list(rows) == ["E", "Rp0.2", "Rm", "Ag", "A"]
    assert abs(float(rows["E"]["livedic_over_reference"]) - 1) <= 0.02
    for name in ("Rp0.2", "Rm"):
        assert abs(float(rows[name]["livedic_over_reference"]) - 1) <= 0.01, rows[name]
    # Ag and A against the same methods on the exact strain: the extensometer's error alone (a few 0.1 %)
    for name in ("Ag", "A"):
        assert abs(float(rows[name]["livedic_over_reference"]) - 1) <= 0.02, rows[name]
    assert (tmp_path / "report" / "report.json").exists() and (tmp_path / "report" / "stress_strain.png").exists()
