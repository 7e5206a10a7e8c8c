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
import tempfile

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


def first_pair(uri: str) -> tuple[Frame, Frame]:
    """The first ``(left, right)`` frames of a ``stereo:`` URI, paired as a stereo session pairs them; closed after."""
    from livedic.acquire.base import SourceError
    from livedic.acquire.sources import open_stereo_source
    with open_stereo_source(uri) as pair_source:
        pair = next(iter(pair_source), None)
        if pair is None:
            raise SourceError(f"{uri} delivered no pair of frames ({pair_source.settings['pairing']})")
        return pair.left, pair.right


def _one_above_other(left_png: str, right_png: str, path: str) -> None:
    """Two rendered previews as one PNG, the left view's row above the right's (each row is already three
    pictures wide), written whole or not at all."""
    import cv2
    import numpy as np
    from livedic.acquire.atomic_file import AtomicFile
    pictures = []
    for name in (left_png, right_png):
        picture = cv2.imread(name, cv2.IMREAD_COLOR)
        if picture is None:
            raise ValueError(f"-o {path}: OpenCV could not read back the preview drawn for one view ({name})")
        pictures.append(picture)
    width = max(picture.shape[1] for picture in pictures)
    padded = [cv2.copyMakeBorder(picture, 0, 0, 0, width - picture.shape[1], cv2.BORDER_CONSTANT,
                                 value=(255, 255, 255)) for picture in pictures]
    ok, encoded = cv2.imencode(".png", np.vstack(padded))
    if not ok:
        raise ValueError(f"-o {path}: OpenCV could not encode the stereo preview")
    with AtomicFile(path, binary=True) as out:
        out.handle.write(encoded.tobytes())
        out.commit()


def preview_command(args: argparse.Namespace) -> int:
    """``livedic preview``: place as ``run`` would, draw, write ``-o``, say what was placed. Returns 0.

    A ``stereo:`` source draws its first pair, the left view above the right: the left placed as ``run`` would
    place it, the right with the same placement, for its speckle contrast and focus.
    """
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
    from livedic.acquire.sources import STEREO_SCHEME, parse_scheme
    stereo = parse_scheme(args.source) == STEREO_SCHEME
    if stereo:
        views = dict(zip(("left", "right"), first_pair(args.source)))
        suggested = None
    else:
        frame, suggested, _ = first_frame(args.source)
        views = {"": frame}
    placement = place_points(views[next(iter(views))].image, wanted, subset=args.subset,
                             suggested_roi=suggested if xy is None else None)
    check_point_count(len(placement.points), wanted.max_points, how=wanted.how(placement.step))
    stage = strain.place(placement.points, p0=placement.points[0], roi=placement.bounds, step=placement.step,
                         subset=args.subset)
    # the check above accepted missing folders (create_folders=True): they are made here, once there is a picture
    os.makedirs(os.path.dirname(os.path.abspath(args.output)), exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=".livedic-preview-", dir=os.path.dirname(os.path.abspath(args.output))) \
            as folder:
        pictures = []
        for view, frame in views.items():
            overlay = setup_overlay(frame.image, placement, stage, subset=args.subset, scale=strain.px_per_mm,
                                    source=f"{view} view of {args.source}" if view else args.source,
                                    bit_depth=(frame.metadata or {}).get("bit_depth"), pixel_format=frame.pixel_format)
            pictures.append(os.path.join(folder, f"{view}.png") if stereo else args.output)
            render_preview(overlay, pictures[-1])
            said = f"{view} view: " if view else ""
            for line in overlay.lines():
                print(f"livedic: {said}{line}", file=sys.stderr)
            for line in overlay.advice():
                print(f"livedic: {said}check: {line}", file=sys.stderr)
        if stereo:
            _one_above_other(pictures[0], pictures[1], args.output)
    print(f"livedic: preview written to {args.output}", file=sys.stderr)
    return 0
