"""Tests of stream/cli/main.py: the parser's one-line errors, the dispatch's exit codes (2 bad input, 1 internal,
3 source lost, 130 interrupted), signed option values, extensions, and ``livedic recover``."""

import logging
import sys

import numpy as np
import pytest

from livedic.acquire.base import SourceError, SourceLost
from livedic.stream.cli.main import (EXIT_BAD_INPUT, EXIT_SOURCE_LOST, _attach_signed_values, _LogLine,
                                     _say_log_lines, build_parser, main)


def _command_raising(error):
    """An extension adding ``livedic boom``, whose handler raises ``error``."""
    def add(commands):
        boom = commands.add_parser("boom")

        def handler(_args):
            raise error
        boom.set_defaults(handler=handler)
    return add


def _one_line(capsys):
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.mark.parametrize("error, code, line", [
    (ValueError("--step 0: give a positive number"), EXIT_BAD_INPUT,
     "livedic: error: --step 0: give a positive number"),
    (SourceError("no camera at gige:x"), EXIT_BAD_INPUT, "livedic: error: no camera at gige:x"),
    (FileNotFoundError("missing.png"), EXIT_BAD_INPUT, "livedic: error: missing.png"),
    (SourceLost("camera lost after 12 frames"), EXIT_SOURCE_LOST, "livedic: error: camera lost after 12 frames"),
    (RuntimeError("a bug"), 1, "livedic: error: internal RuntimeError: a bug"),
    (KeyboardInterrupt(), 130, "livedic: interrupted"),
])
def test_errors_are_one_line_with_their_exit_code(error, code, line, capsys):
    assert main(["boom"], extensions=[_command_raising(error)]) == code
    assert _one_line(capsys) == line


def test_livedic_debug_shows_the_traceback(monkeypatch):
    monkeypatch.setenv("LIVEDIC_DEBUG", "1")
    with pytest.raises(ValueError, match="shown"):
        main(["boom"], extensions=[_command_raising(ValueError("shown"))])


def test_a_bad_option_is_one_line_pointing_to_help(capsys):
    assert main(["export", "x.mcap"]) == EXIT_BAD_INPUT
    line = _one_line(capsys)
    assert line.startswith("livedic: error: the following arguments are required: -o/--output")
    assert line.endswith("(see livedic export --help)")
    assert main(["nonsense"]) == EXIT_BAD_INPUT
    assert _one_line(capsys).startswith("livedic: error: argument COMMAND: invalid choice: 'nonsense'")


def test_no_command_prints_the_help_and_help_exits_0(capsys):
    assert main([]) == EXIT_BAD_INPUT
    out = capsys.readouterr().out
    assert all(name in out for name in ("run", "measure", "replay", "export", "report", "recover", "cameras",
                                        "preview"))
    assert main(["--help"]) == 0 and "usage: livedic" in capsys.readouterr().out


def test_signed_list_values_are_attached_to_their_option():
    assert _attach_signed_values(["run", "--color-range", "-2,2", "--p0", "1,2"]) == \
        ["run", "--color-range=-2,2", "--p0", "1,2"]
    assert _attach_signed_values(["--color-range", "-.5,1"]) == ["--color-range=-.5,1"]
    assert _attach_signed_values(["--color-range", "--other"]) == ["--color-range", "--other"]
    assert _attach_signed_values(["--color-range"]) == ["--color-range"]
    assert _attach_signed_values(["--step", "-2"]) == ["--step", "-2"]
    assert build_parser().parse_args(_attach_signed_values(["run", "--color-range", "-2,2"])).color_range == "-2,2"


def test_log_lines_are_said_as_livedic_lines_once(capsys):
    logger = logging.getLogger("livedic")
    before = list(logger.handlers)
    try:
        _say_log_lines()
        _say_log_lines()
        ours = [h for h in logger.handlers if isinstance(h, _LogLine)]
        assert len(ours) == 1
        ours[0].setStream(sys.stderr)                   # one made earlier holds the stderr of its time
        logging.getLogger("livedic.acquire.recording.reader").warning("note: the file is truncated")
        assert capsys.readouterr().err == "livedic: note: the file is truncated\n"
    finally:
        logger.handlers[:] = before


def test_recover_writes_an_indexed_copy_and_refuses_to_overwrite(tmp_path, capsys):
    from livedic.acquire.base import Frame
    from livedic.acquire.recording.source import McapSource
    from livedic.acquire.recording.writer import Recorder
    path, fixed = tmp_path / "whole.mcap", tmp_path / "fixed.mcap"
    with Recorder(str(path), {"command": "test"}, start_time_ns=0) as recorder:
        for i in range(3):
            recorder.write_frame(Frame(i, 1000 * i, np.full((6, 8), i, np.uint8), "Mono8"))
        recorder.write_event("note", "one event")
    assert main(["recover", str(path), "-o", str(fixed)]) == 0          # what a cut file keeps: acquire's tests
    assert _one_line(capsys) == (f"livedic: {path} was complete; wrote {fixed} with 3 frames, 0 result sets and "
                                 f"1 events")
    assert [int(f.image[0, 0]) for f in McapSource(fixed)] == [0, 1, 2]
    before = fixed.read_bytes()
    assert main(["recover", str(path), "-o", str(fixed)]) == EXIT_BAD_INPUT
    assert _one_line(capsys) == (f"livedic: error: {fixed} already exists: choose a new name, or add --overwrite to "
                                 f"replace it")
    assert fixed.read_bytes() == before
    assert main(["recover", str(path), "-o", str(fixed), "--overwrite"]) == 0
