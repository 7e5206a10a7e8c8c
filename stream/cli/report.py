"""``livedic report FILE.mcap -o DIR``: the tensile test report of a recording (E, Rp0.2, Rm, Ag, A, ReH, ReL, Ae;
ISO 6892-1).

``report_command`` runs it (``stream.export.report.report_recording``); ``add_report_arguments`` declares its options.
"""

from __future__ import annotations

import argparse

from livedic.dic.tensile.yielding import CurveShape
from livedic.stream.export.force import stress_from_args
from livedic.stream.export.notes import say
from livedic.stream.export.report_verification import VERIFICATION_KEY, load_verification
from livedic.stream.export.report import (CURVE_SHAPE_KEY, POISSON_KEY, PROPERTY_KEYS, PROPERTY_TITLES, REPORT_FILES,
                                          YIELD_KEYS, report_recording)
from livedic.stream.stages.strain import add_strain_arguments, overrides_from_args
from livedic.stream.stages.stress import add_stress_arguments


def add_report_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``livedic report`` arguments to an ``argparse`` (sub)parser."""
    parser.add_argument("recording", metavar="FILE.mcap", help="a recording made by livedic run (may be truncated)")
    parser.add_argument("-o", "--output", required=True, metavar="DIR", help="folder to write (created if missing)")
    parser.add_argument("--overwrite", action="store_true", help="replace the files if DIR already holds them")
    add_stress_arguments(parser)
    add_strain_arguments(parser, recorded=True)
    parser.add_argument("--verification", metavar="FILE.json",
                        help="the extensometer's ISO 9513 verification (livedic verify -o FILE.json on your own frames, or "
                             "livedic bench extensometer -o FILE.json): "
                             "the report states its class; without it, that the class was not verified")


def report_command(args: argparse.Namespace) -> int:
    """``livedic report FILE.mcap -o DIR [--load csv:FILE] [--area | --width --thickness]``; the exit code.

    Without ``--load`` the force recorded on ``/machine/force`` (``stream.export.force.stress_from_args``).
    """
    overrides = overrides_from_args(args)              # bad values: one line, before anything is read
    stress, stress_notes = stress_from_args(args)
    verification = load_verification(args.verification) if args.verification is not None else None
    if stress is None:
        raise ValueError("the report needs the machine's force: --load csv:FILE with the cross-section (--area MM2, "
                         "or --width MM --thickness MM), or a recording that holds it (/machine/force)")
    report = report_recording(args.recording, args.output, stress=stress, strain=overrides,
                              overwrite=args.overwrite, verification=verification)
    for note in stress_notes + report["source"]["notes"]:
        say(f"note: {note}")
    values = []
    continuous = report[CURVE_SHAPE_KEY]["value"] == CurveShape.CONTINUOUS.name.lower()
    for key in PROPERTY_KEYS:
        name, unit = PROPERTY_TITLES[key]
        value = report[key]["value"]
        if continuous and key in YIELD_KEYS:          # no yield phenomenon: report.md says why
            continue
        values.append(f"{name} {'n/a' if value is None else f'{value:.4g} {unit}'}")
    nu = report[POISSON_KEY]["value"]
    values.append(f"Poisson's ratio (elastic) {'n/a' if nu is None else f'{nu:.3f}'}")
    verified = report[VERIFICATION_KEY]
    values.append(f"ISO 9513 class {verified['class'] or 'none'} (verified)" if verified["verified"]
                  else "ISO 9513 class not verified")
    say(f"report: {', '.join(values)}; written to {args.output}/ ({', '.join(REPORT_FILES)})")
    return 0
