"""``livedic preview``: a test's set-up drawn before it starts (the source's first frame, placed as ``run`` would).

``add_preview_arguments`` declares its options, ``preview_command`` runs it; the drawing is
``stream.session.preview``'s.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from livedic.acquire.base import Frame

import os
import sys

from livedic.stream.session.preview import render_preview, setup_overlay


def add_preview_arguments(parser: argparse.ArgumentParser) -> None:
    """``livedic preview``'s options: the source, the output, and ``livedic run``'s placement options."""
    from livedic.stream.session.config import DEFAULT_SOURCE, add_subset_argument
    from livedic.stream.session.points import add_point_arguments
    from livedic.stream.stages.strain import add_strain_arguments
    parser.add_argument("--source", default=DEFAULT_SOURCE, metavar="URI",
                        help="frame source, as for livedic run (default synthetic:tensile): its first frame is drawn")
    parser.add_argument("-o", "--output", required=True, metavar="PREVIEW.png", help="the picture to write")
    add_point_arguments(parser)
    add_subset_argument(parser)
    add_strain_arguments(parser)


def first_frame(uri: str) -> tuple[Frame, Any, dict]:
    """``(frame, the source's suggested ROI or None, its settings)``: the first frame of ``uri``; the source closed.

    The simulator renders only what the first frame needs.
    """
    from livedic.acquire import sources
    from livedic.acquire.base import SourceError
    from livedic.stream.session.points import default_roi
    options = {}
    if sources.parse_scheme(uri) == "synthetic" and "frames=" not in uri:
        options["frames"] = 2
    source = sources.open_source(uri, **options)
    try:
        if hasattr(source, "prepare"):
            source.prepare()
        try:
            frame = next(iter(source))
        except StopIteration:
            raise SourceError(f"{uri} delivered no frame") from None
        return frame, default_roi(source), dict(source.settings or {})
    finally:
        source.close()


def preview_command(args: argparse.Namespace) -> int:
    """``livedic preview``: place as ``run`` would, draw, write ``-o``, say what was placed. Returns 0."""
    from livedic.stream.session.config import PointsConfig
    from livedic.stream.session.parsing import parse_p0
    from livedic.stream.output.files import check_output_file
    from livedic.stream.session.points import check_point_count, place_points, read_points_csv
    from livedic.stream.stages.strain import StrainConfig
    if not args.output.lower().endswith(".png"):
        raise ValueError(f"-o {args.output}: the preview is a PNG picture: name it PREVIEW.png")
    check_output_file(args.output, "-o", create_folders=True)
    strain = StrainConfig.from_args(args)
    xy = read_points_csv(args.points) if args.points else None
    wanted = PointsConfig(points_file=args.points, xy=xy, step=args.step, n_points=args.n_points,
                          p0=parse_p0(args.p0), max_points=args.max_points, **PointsConfig.region_from_args(args))
    frame, suggested, _ = first_frame(args.source)
    placement = place_points(frame.image, wanted, subset=args.subset,
                             suggested_roi=suggested if xy is None else None)
    check_point_count(len(placement.points), wanted.max_points, how=wanted.how(placement.step))
    stage = strain.place(placement.points, p0=placement.points[0], roi=placement.bounds, step=placement.step,
                         subset=args.subset)
    overlay = setup_overlay(frame.image, placement, stage, subset=args.subset, scale=strain.px_per_mm,
                            source=args.source, bit_depth=(frame.metadata or {}).get("bit_depth"),
                            pixel_format=frame.pixel_format)
    # the check above accepted missing folders (create_folders=True): they are made here, once there is a picture
    os.makedirs(os.path.dirname(os.path.abspath(args.output)), exist_ok=True)
    render_preview(overlay, args.output)
    for line in overlay.lines():
        print(f"livedic: {line}", file=sys.stderr)
    for line in overlay.advice():
        print(f"livedic: check: {line}", file=sys.stderr)
    print(f"livedic: preview written to {args.output}", file=sys.stderr)
    return 0
