"""``livedic bench tracker``: every stage reported, results kept and compared bit for bit, profiles summarised.

Timings are printed, never asserted.
"""

import numpy as np

from livedic.bench.cli import main
from livedic.dic import TRACKER_STAGES


def test_small_run_reports_every_stage_and_compares_its_results(tmp_path, capsys):
    saved = tmp_path / "results.npz"
    assert main(["bench", "tracker", "--size", "256", "--frames", "8", "--save", str(saved)]) == 0
    out = capsys.readouterr().out
    for stage in TRACKER_STAGES + ("other", "total (track)", "bare kernel", "tracker / bare kernel"):
        assert stage in out
    assert main(["bench", "tracker", "--size", "256", "--frames", "8", "--compare", str(saved)]) == 0
    assert "identical bit for bit" in capsys.readouterr().out
    arrays = dict(np.load(saved))
    arrays["3/u"] = np.nextafter(arrays["3/u"], np.inf)          # one ulp off: a difference
    np.savez(saved, **arrays)
    assert main(["bench", "tracker", "--size", "256", "--frames", "8", "--compare", str(saved)]) == 1
    assert "1 differ, first: 3/u" in capsys.readouterr().out


def test_stacks_summarises_where_the_tracker_spends_its_samples(tmp_path, capsys):
    profile = tmp_path / "prof.txt"
    profile.write_text(
        "<module> (livedic:10);KeyFrameTracker.track (dic/key_frames.py:253);refine_prepared (dic/subpixel/icgn.py:9) 6\n"
        "<module> (livedic:10);KeyFrameTracker.track (dic/key_frames.py:253);prefilter (dic/bspline.py:3) 2\n"
        "<module> (livedic:10);warm_up (stream/session/session.py:1);KeyFrameTracker.track (dic/key_frames.py:1);x (y:1) 9\n"
        "<module> (livedic:10);Recorder.write (acquire/recording/writer.py:5) 7\n")
    assert main(["bench", "tracker", "--stacks", str(profile)]) == 0
    out = capsys.readouterr().out
    assert "8 samples inside KeyFrameTracker.track" in out
    assert "75.0 %  refine_prepared (dic/subpixel/icgn.py)" in out and "25.0 %  prefilter" in out


def test_bad_arguments_are_one_line_exit_2(capsys, tmp_path):
    assert main(["bench", "tracker", "--frames", "2"]) == 2
    assert main(["bench", "tracker", "--stacks", str(tmp_path / "missing.txt")]) == 2
    assert capsys.readouterr().err.count("\n") == 2


def test_interpolation_option_tracks_with_the_quintic_and_refuses_a_bad_name(capsys):
    assert main(["bench", "tracker", "--size", "256", "--frames", "6", "--interpolation", "bspline5"]) == 0
    assert "interpolation bspline5" in capsys.readouterr().out
    assert main(["bench", "tracker", "--frames", "6", "--interpolation", "cubic"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unknown interpolation 'cubic'" in err
