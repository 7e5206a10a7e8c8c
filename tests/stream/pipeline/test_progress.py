"""Tests of stream/pipeline/progress.py: --progress auto|on|off, and the one line redrawn in place on stderr."""

import argparse
import io

import pytest

from livedic.stream.pipeline import progress
from livedic.stream.pipeline.progress import PROGRESS_CHOICES, ProgressBar, add_progress_argument, progress_enabled


class Terminal(io.StringIO):
    def isatty(self):
        return True


@pytest.mark.parametrize("choice, terminal, shown", [("on", False, True), ("off", True, False),
                                                     ("auto", True, True), ("auto", False, False)])
def test_auto_shows_the_bar_only_on_a_terminal(choice, terminal, shown):
    assert progress_enabled(choice, Terminal() if terminal else io.StringIO()) is shown


def test_the_option_takes_the_three_choices_and_defaults_to_auto(capsys):
    parser = add_progress_argument(argparse.ArgumentParser(prog="livedic"))
    assert parser.parse_args([]).progress == "auto" and PROGRESS_CHOICES == ("auto", "on", "off")
    with pytest.raises(SystemExit):
        parser.parse_args(["--progress", "sometimes"])
    assert "invalid choice: 'sometimes'" in capsys.readouterr().err


def test_the_bar_shows_the_share_done_and_ends_its_line():
    out = io.StringIO()
    bar = ProgressBar(8, stream=out, width=8)
    bar.update(2, "tracking", force=True)
    assert out.getvalue() == "\r[##......] 2/8 tracking\033[K"
    bar.update(20, force=True)                                # more than the total: a full bar, never more
    assert out.getvalue().endswith("\r[########] 20/8 \033[K")
    bar.clear()
    assert out.getvalue().endswith("\r\033[K")
    bar.close()
    bar.close()                                               # once: one newline
    assert out.getvalue().endswith("\033[K\n") and out.getvalue().count("\n") == 1


def test_without_a_total_the_count_alone():
    out = io.StringIO()
    ProgressBar(stream=out).update(42, "frames", force=True)
    assert out.getvalue() == "\r42 frames\033[K"


def test_redraws_are_limited_by_the_rate_unless_forced(monkeypatch):
    now = [100.0]
    monkeypatch.setattr(progress.time, "monotonic", lambda: now[0])
    out = io.StringIO()
    bar = ProgressBar(10, stream=out, hz=4.0)
    bar.update(1)
    assert out.getvalue().count("\r") == 1 and not bar.due()
    now[0] += 0.1
    bar.update(2, "skipped")
    assert out.getvalue().count("\r") == 1 and bar.last_text == "skipped"   # the text is kept for later
    bar.update(3, force=True)
    assert out.getvalue().count("\r") == 2
    now[0] += 0.25
    assert bar.due()


def test_a_disabled_bar_writes_nothing():
    out = io.StringIO()
    bar = ProgressBar(5, enabled=False, stream=out)
    bar.update(1, force=True)
    bar.clear()
    bar.close()
    assert out.getvalue() == "" and not bar.due()
