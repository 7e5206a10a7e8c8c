"""``livedic export FILE.mcap -o DIR``: a recording's results as CSV files, maps, an overlay video and VTK.

``export_command`` runs it (``stream.export.export.export_recording``); ``add_export_arguments`` declares its options.
"""

from __future__ import annotations

import argparse
import os

from livedic.stream.export.export import export_recording
from livedic.stream.export.force import stress_from_args
from livedic.stream.export.notes import plural, say
from livedic.stream.export.stop import ExportStopped, StopSignals
from livedic.stream.export.field_export import FieldOptions, add_field_arguments
from livedic.stream.pipeline.progress import ProgressBar, add_progress_argument, progress_enabled
from livedic.stream.stages.strain import add_strain_arguments, overrides_from_args
from livedic.stream.stages.stress import add_stress_arguments


def add_export_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``livedic export`` arguments to an ``argparse`` (sub)parser."""
    parser.add_argument("recording", metavar="FILE.mcap", help="a recording made by livedic run (may be truncated)")
    parser.add_argument("-o", "--output", required=True, metavar="DIR", help="folder to write (created if missing)")
    parser.add_argument("--overwrite", action="store_true", help="replace the files if DIR already holds them")
    add_strain_arguments(parser, recorded=True)
    add_stress_arguments(parser)
    add_field_arguments(parser)
    add_progress_argument(parser)


def export_command(args: argparse.Namespace) -> int:
    """``livedic export FILE.mcap -o DIR [--overwrite] [strain options] [field options]``; returns the exit code.

    Stopped by SIGINT or SIGTERM: one line saying what the folder holds, exit 128 + the signal's
    number (130 for Ctrl-C, 143 for SIGTERM), as a shell reports a command a signal ended.
    """
    overrides = overrides_from_args(args)              # bad values: one line, before anything is read
    fields = FieldOptions.from_args(args)
    stress, stress_notes = stress_from_args(args)
    bar = ProgressBar(None, enabled=progress_enabled(args.progress))
    try:
        with StopSignals() as signals:
            summary = export_recording(args.recording, args.output, overwrite=args.overwrite, strain=overrides,
                                       stress=stress, fields=fields, stop=signals.check, progress=bar)
    except ExportStopped as stopped:
        bar.close()
        say(f"export stopped on {stopped.signal_name} {stopped.state}")
        return 128 + stopped.signum
    finally:
        bar.close()
    for note in stress_notes + summary["notes"]:
        say(f"note: {note}")
    if summary["strain"]:
        say(summary["strain"])
    state = " (what could be recovered from the truncated recording)" if summary["truncated"] else ""
    say(f"exported {summary['frames']} frames x {summary['points']} points{state}, P0 = point "
        f"{summary['p0_id']} ({summary['p0_rows']} rows), {plural(summary['events'], 'event')} "
        f"to {summary['directory']}/ "
        f"({', '.join(os.path.basename(name) for name in summary['files'])})")
    if summary["fields"] is not None:
        say(f"and {summary['fields'].written(fields)}")
    if summary["stress"] is not None:
        stress_summary = summary["stress"]
        for note in stress_summary.get("notes", []):
            say(f"note: {note}")
        if stress_summary["uniform_frame"] >= 0:
            say(f"stress-strain: force at {stress_summary['frames_with_force']} of {summary['frames']} frames, "
                f"maximum force at frame {stress_summary['uniform_frame']} (true values up to it)")
    return 0
