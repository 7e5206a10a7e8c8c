"""``livedic bench peers``: the cases' exact truth, the 12-bit scaling, the RMSE arithmetic, the peers' plumbing.

No real peer is needed: a peer not given is "not installed", and stand-in executables (small Python scripts
written here) play OpenCorr's driver to check how a peer's table, its failures and the ratio are read.
"""

import math
import os
import stat
import sys

import numpy as np
import pytest

from livedic.bench.cli import main
from livedic.bench.peers import (GREY_RANGE, OPENCORR, SUNDIC, Case, PeerStatus, grid, quantise, render_clean,
                                 render_pair, report_case, run_case, score, verdicts)

SMALL = 96            # px: a case small enough for a test, 36 grid points
SHIFT = (0.3, 0.7)


def _case(generator="fft-filtered noise", bits=8, shifts=(SHIFT,)):
    return Case(generator, bits, tuple(shifts), SMALL)


@pytest.mark.parametrize("generator", ["fft-filtered noise", "gaussian dots"])
@pytest.mark.parametrize("bits", [8, 12])
def test_a_rendered_case_carries_its_shift_exactly(generator, bits):
    """Noise-free, livedic's biquintic IC-GN reads the declared shift on every point: the truth is the shift."""
    result = run_case(_case(generator, bits, ((0.3, 0.7), (0.85, 0.2))), settings=(("bspline5", "none"),),
                      noise_sigma_8bit=0.0)
    (livedic,) = result.livedic
    assert livedic.ok == livedic.points == 2 * len(grid(SMALL))
    assert livedic.rmse_u < 0.004 and livedic.rmse_v < 0.004


def test_noise_sigma_two_gives_the_expected_random_error_and_no_offset():
    """With noise sigma 2 the error grows but stays centred on the truth (the mean over the grid is tiny)."""
    from livedic.dic import measure

    case = _case(shifts=(SHIFT,))
    reference, deformed = render_pair(case, SHIFT, 0)
    m = measure(reference, deformed, grid(SMALL), subset=21, subpixel="icgn")
    assert m.ok.all()
    assert abs(np.mean(m.u - SHIFT[0])) < 0.01 and abs(np.mean(m.v - SHIFT[1])) < 0.01
    assert 0.002 < np.sqrt(np.mean((m.u - SHIFT[0]) ** 2)) < 0.05


def test_the_reference_spans_the_grey_range_and_twelve_bit_scales_image_and_noise():
    reference, _ = render_clean("fft-filtered noise", SMALL, SHIFT)
    assert reference.min() == pytest.approx(GREY_RANGE[0]) and reference.max() == pytest.approx(GREY_RANGE[1])
    clean8, clean12 = quantise(reference, 8, 0.0, 1), quantise(reference, 12, 0.0, 1)
    assert clean8.dtype == np.uint8 and clean12.dtype == np.uint16 and clean12.max() <= 4095
    np.testing.assert_allclose(clean12, reference * 4095 / 255, atol=0.5)
    noise8 = quantise(reference, 8, 2.0, 7).astype(float) - clean8
    noise12 = quantise(reference, 12, 2.0, 7).astype(float) - clean12
    assert np.std(noise8) == pytest.approx(2.0, rel=0.05)
    assert np.std(noise12) == pytest.approx(2.0 * 4095 / 255, rel=0.05)


def test_score_pools_the_ok_points_of_every_pair():
    ok = [np.array([True, True, False]), np.array([True, False])]
    s = score("x", [np.array([0.3, -0.3, 9.0]), np.array([0.0, 9.0])], [np.array([0.4, 0.4, 9.0]),
                                                                         np.array([-0.4, 9.0])], ok)
    assert (s.ok, s.points) == (3, 5)
    assert s.rmse_u == pytest.approx(math.sqrt(0.06)) and s.rmse_v == pytest.approx(0.4)
    assert s.rmse == pytest.approx(math.sqrt((0.06 + 0.16) / 2))
    none = score("x", [np.array([1.0])], [np.array([1.0])], [np.array([False])])
    assert none.status is PeerStatus.FAILED and math.isnan(none.rmse)


def test_peers_not_given_are_not_installed_and_give_no_ratio(capsys):
    result = run_case(_case(), settings=(("bspline3", "none"),))
    assert [(p.code, p.status) for p in result.peers] == [(SUNDIC, PeerStatus.NOT_INSTALLED),
                                                        (OPENCORR, PeerStatus.NOT_INSTALLED)]
    assert result.best_peer() is None and math.isnan(result.ratio(result.livedic[0]))
    assert all(math.isnan(ratio) for ratio in verdicts([result]).values())
    report_case(result, print)
    assert capsys.readouterr().out.count("not installed") == 2


def _stand_in(tmp_path, body):
    """An executable Python script standing in for OpenCorr's driver: argv = REF TAR POIS OUT RADIUS."""
    path = tmp_path / "opencorr_stand_in"
    path.write_text(f"#!{sys.executable}\nimport sys\nref, tar, pois, out, radius = sys.argv[1:6]\n{body}\n")
    path.chmod(path.stat().st_mode | stat.S_IXUSR)
    return str(path)


def test_a_peer_table_is_read_on_the_grid_and_sets_the_ratio(tmp_path):
    """A stand-in that reads every point as (0, 0) and fails every other one: its RMSE is exactly the shift's."""
    body = ("rows = [l.strip() for l in open(pois) if l.strip()]\n"
            "with open(out, 'w') as f:\n"
            "    f.write('x,y,u,v,zncc,iteration,convergence\\n')\n"
            "    for i, r in enumerate(rows):\n"
            "        f.write(f'{r},0,0,{0.9 if i % 2 == 0 else -4},3,0\\n')\n")
    result = run_case(_case(), settings=(("bspline3", "none"),), opencorr_bin=_stand_in(tmp_path, body))
    peer = result.peers[1]
    assert peer.status is PeerStatus.MEASURED
    assert (peer.ok, peer.points) == ((len(grid(SMALL)) + 1) // 2, len(grid(SMALL)))
    assert peer.rmse_u == pytest.approx(SHIFT[0]) and peer.rmse_v == pytest.approx(SHIFT[1])
    assert result.best_peer() is peer
    ratio = result.ratio(result.livedic[0])
    assert ratio == pytest.approx(result.livedic[0].rmse / peer.rmse) and ratio < 0.9
    assert verdicts([result]) == {"livedic bspline3/none": pytest.approx(ratio)}


def test_a_failing_peer_is_reported_with_its_own_message(tmp_path):
    body = "sys.stderr.write('cannot read a grey image: ' + ref + '\\n'); sys.exit(1)"
    result = run_case(_case(), settings=(("bspline3", "none"),), opencorr_bin=_stand_in(tmp_path, body))
    peer = result.peers[1]
    assert peer.status is PeerStatus.FAILED and "exit code 1: cannot read a grey image" in peer.reason
    assert result.best_peer() is None


def test_cli_peer_locations_are_checked_in_one_line_exit_2(tmp_path, capsys):
    assert main(["bench", "peers", "--quick", "--opencorr-bin", str(tmp_path / "absent")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--opencorr-bin" in err[0] and "not an executable file" in err[0]
    no_sundic = _stand_in(tmp_path, "sys.exit(1)")      # a "python" that cannot import sundic
    assert main(["bench", "peers", "--quick", "--sundic-python", no_sundic]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot import sundic" in err[0]


def test_cli_unwritable_output_is_one_line_exit_2(tmp_path, capsys):
    assert main(["bench", "peers", "--quick", "-o", os.path.join(str(tmp_path), "absent", "out.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "-o" in err[0]


def test_the_noise_prediction_matches_livedic_on_a_noisy_case():
    """The case's first-order prediction is what livedic's IC-GN reads with noise sigma 2 (within the scatter of
    a few hundred points)."""
    result = run_case(Case("fft-filtered noise", 8, (SHIFT, (0.6, 0.1)), 160), settings=(("bspline5", "gaussian:0.6"),))
    assert result.livedic[0].rmse == pytest.approx(result.predicted_rmse, rel=0.15)
