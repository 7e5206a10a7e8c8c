"""``livedic verify REFERENCE IMAGES...``: the axial extensometer's ISO 9513 class from a user's own frames.

The in-situ assessment of EN 4861:2020 (known displacements before the test) on the lab's own camera, lens,
light and speckle: each image is a reading at a known elongation of the gauge length, 0 for static frames
and rigid translations of the specimen or the camera (every image's default), or the value an
``--elongations FILE.csv`` (columns ``image,elongation_um``: a calibrator moving one grip by known amounts)
gives it. Images of one known elongation form one step (bias = mean reading - known, resolution = half the
range of the readings), classified by ``dic.strain.iso9513.classify`` (ISO 9513:2012 Table 2). Known
elongations are in micrometres on the specimen, so a non-zero one needs the scale (``--scale`` or a
``--calibration`` with the plane's px/mm); without any, the class is not claimed (only the zero point was
verified: ``dic.strain.iso9513.StepReason.NO_ELONGATION``).

The images are tracked in the order given as ``livedic run`` tracks a camera's frames: the points placed
on the reference as ``run`` places them (``--roi``, ``--step``, ``--p0`` ...), the session's tracker
(``TrackingConfig.tracker``: KeyFrameTracker, IC-GN, reference updates) and the session's axial extensometer
(``StrainConfig.place``: ``--gauge-length`` px centred on P0 along y, ``--extensometer-ends``; undistorted
with ``--calibration``). ``-o`` writes the verification file ``livedic bench extensometer -o`` writes
(``stream.export.report_verification``), its source marked as the user's frames, which ``livedic report
--verification`` reads.

Bad input (fewer than two images besides the reference, images of different sizes, an elongations file
that does not parse or names an image not given, a gauge length that does not fit) is one line, exit 2,
before anything is written.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from livedic.stream.session.config import TrackingConfig
from livedic.stream.session.options import add_config_arguments, config_values
from livedic.stream.session.parsing import UsageError
from livedic.stream.session.points import add_point_arguments

ELONGATION_COLUMNS = ("image", "elongation_um")
UM_PER_MM = 1000.0


def add_verify_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``livedic verify`` options to an ``argparse`` (sub)parser."""
    from livedic.dic.strain.extensometer import END_FITS
    from livedic.stream.stages.strain import DEFAULT_AXIAL_END_FIT
    parser.add_argument("reference", metavar="REFERENCE", help="the reference image (8/16-bit grey PNG or TIFF)")
    parser.add_argument("images", nargs="+", metavar="IMAGES",
                        help="images of known elongation, same size (files, folders or quoted globs, in natural "
                             "order): static frames and rigid translations are 0, others from --elongations")
    parser.add_argument("--gauge-length", type=float, required=True, metavar="PX",
                        help="the axial extensometer's length L0 in px, along y, centred on P0 (as livedic run)")
    parser.add_argument("--scale", type=float, metavar="PX_PER_MM",
                        help="pixels per millimetre on the specimen: the ISO 9513 absolute (um) limits, and "
                             "--elongations in um")
    parser.add_argument("--calibration", metavar="CAL.json",
                        help="camera calibration from livedic calibrate: points undistorted; its px/mm is the scale")
    parser.add_argument("--elongations", metavar="FILE.csv",
                        help="known elongations: CSV with header image,elongation_um (image: a file as given or its "
                             "name); images not listed are 0 (static, rigid motion)")
    parser.add_argument("--extensometer-ends", choices=END_FITS, default=DEFAULT_AXIAL_END_FIT,
                        help=f"how the axial extensometer's ends are fitted (as livedic run; default "
                             f"{DEFAULT_AXIAL_END_FIT})")
    add_point_arguments(parser)
    add_config_arguments(parser, TrackingConfig)
    parser.add_argument("-o", "--output", metavar="FILE.json",
                        help="the verification file for livedic report --verification")


@dataclass(frozen=True)
class KnownSteps:
    """The images grouped by known elongation: ``values_um`` increasing, ``members[k]`` the image indices
    (into the images after the reference) of step k."""
    values_um: tuple[float, ...]
    members: tuple[tuple[int, ...], ...]


def read_elongations(path: str | None, reference: str, images: Sequence[str]) -> list[float]:
    """The known elongation of each image (um): 0 unless ``path`` (CSV ``image,elongation_um``) names it.

    Raises
    ------
    UsageError
        A file that does not parse, lacks the columns, names an image not given (or one twice), or gives the
        reference a non-zero elongation.
    """
    known = [0.0] * len(images)
    if path is None:
        return known
    rows = _elongation_rows(path)
    for line, name, value in rows:
        if _matches(name, reference):
            if value != 0:
                raise UsageError(f"{path} line {line}: the reference {reference} is the zero of elongation, "
                                 f"not {value:g} um: give images after it their elongation from it")
            continue
        found = [k for k, image in enumerate(images) if _matches(name, image)]
        if len(found) != 1:
            what = "names no image given" if not found else "matches several images: give the path as given"
            raise UsageError(f"{path} line {line}: {name!r} {what} ({len(images)} images after the reference)")
        known[found[0]] = value
    return known


def _matches(name: str, image: str) -> bool:
    return name == image or os.path.normpath(name) == os.path.normpath(image) or name == os.path.basename(image)


def _elongation_rows(path: str) -> list[tuple[int, str, float]]:
    """(line, image, elongation um) of each row of an elongations CSV."""
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            reader = csv.DictReader(handle)
            columns = [c.strip() for c in (reader.fieldnames or [])]
            if any(c not in columns for c in ELONGATION_COLUMNS):
                raise UsageError(f"--elongations {path}: needs the header {','.join(ELONGATION_COLUMNS)}, found "
                                 f"{','.join(columns) or 'none'}")
            rows = []
            for row in reader:
                row = {(k or "").strip(): (v or "").strip() for k, v in row.items()}
                rows.append((reader.line_num, row["image"], _um(row["elongation_um"], path, reader.line_num)))
    except (OSError, UnicodeDecodeError, csv.Error) as error:
        raise UsageError(f"--elongations {path} cannot be read ({error}): give a CSV with header "
                         f"{','.join(ELONGATION_COLUMNS)}") from None
    seen = [name for _, name, _ in rows]
    twice = sorted({name for name in seen if seen.count(name) > 1})
    if twice:
        raise UsageError(f"--elongations {path}: {twice[0]!r} is listed twice: one known elongation per image")
    return rows


def _um(text: str, path: str, line: int) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise UsageError(f"--elongations {path} line {line}: elongation_um {text!r} is not a number (micrometres)")
    return value


def group_steps(known_um: Sequence[float]) -> KnownSteps:
    """Images of one known elongation form one step; steps by increasing elongation."""
    values = tuple(sorted(set(float(v) for v in known_um)))
    members = tuple(tuple(k for k, v in enumerate(known_um) if float(v) == value) for value in values)
    return KnownSteps(values, members)


def verify_command(args: argparse.Namespace) -> int:
    """``livedic verify`` with parsed ``args``; returns the exit code (bad input: ``UsageError``)."""
    from livedic.stream.export.report_verification import verification_table_lines, write_verification
    from livedic.stream.output.files import check_output_file
    started = time.perf_counter()
    tracking = TrackingConfig(**config_values(TrackingConfig, args))
    strain = _strain_config(args)
    paths = _image_paths(args)
    known_um = read_elongations(args.elongations, args.reference, paths)
    scale = strain.px_per_mm
    if any(v != 0 for v in known_um) and scale is None:
        raise UsageError("--elongations are in micrometres on the specimen: give --scale PX_PER_MM or a "
                         "--calibration that measured the specimen plane (livedic calibrate --plane)")
    if args.output is not None:
        check_output_file(args.output, "-o")
    reference, images = _read_images(args.reference, paths)
    placement, stage = _place(args, strain, tracking, reference)
    readings, lost = _track(tracking, reference, placement.points, stage, images)
    steps = group_steps(known_um)
    entry = _entry(steps, readings, args.gauge_length, scale, paths)
    print(f"livedic verify: {len(paths)} image(s) against {args.reference}; {len(placement.points)} points "
          f"({placement.describe()}), subset {tracking.subset} px, {tracking.search}+{tracking.subpixel}; axial "
          f"extensometer L0 {args.gauge_length:g} px on P0 {placement.points[0][0]:g},{placement.points[0][1]:g}, "
          f"{strain.axial_end_fit} ends; scale "
          f"{f'{scale:g} px/mm' if scale else 'none (relative limits only, zero steps not classified)'}")
    for line in verification_table_lines(entry):
        print(line)
    print(f"points not ok, summed over the {len(images)} images: {lost} of {len(placement.points) * len(images)}")
    if args.output is not None:
        write_verification(args.output, _document(args, tracking, strain, placement, reference.shape, paths,
                                                  known_um, entry, lost, time.perf_counter() - started))
        print(f"livedic: written to {args.output}", file=sys.stderr)
    return 0


def _strain_config(args: argparse.Namespace) -> Any:
    """The session's strain settings holding only the axial extensometer of ``--gauge-length`` px."""
    from livedic.stream.stages.strain import StrainConfig
    if not (math.isfinite(args.gauge_length) and args.gauge_length > 0):
        raise UsageError(f"--gauge-length must be a positive number of px, got {args.gauge_length:g}")
    calibration = None
    if args.calibration is not None:
        from livedic.acquire.calibration import read_calibration
        calibration = read_calibration(args.calibration)
    # StrainConfig's gauge length is in mm when there is a scale (it refuses --scale beside a calibration's own)
    scale = args.scale if args.scale is not None else (calibration.px_per_mm if calibration is not None else None)
    return StrainConfig(scale=args.scale, calibration=calibration, axial_end_fit=args.extensometer_ends,
                        gauge_length=args.gauge_length / scale if scale else args.gauge_length)


def _image_paths(args: argparse.Namespace) -> list[str]:
    """IMAGES as files (folders and globs expanded, as livedic calibrate takes them): at least two."""
    from livedic.acquire.calibration import expand_images
    paths = expand_images(args.images)
    if len(paths) < 2:
        raise UsageError(f"verify needs the reference and at least 2 images (readings at one known elongation give "
                         f"its resolution), got {len(paths)} image(s) besides {args.reference}")
    return paths


def _read_images(reference_path: str, paths: Sequence[str]) -> tuple[np.ndarray, list[np.ndarray]]:
    """Every image read and checked against the reference's size before any work."""
    from livedic.acquire.files.image_file import read_same_size_images
    images, notes = read_same_size_images([reference_path, *paths], "all images")
    for note in notes:
        print(f"livedic: note: {note}", file=sys.stderr)
    return images[0], images[1:]


def _place(args: argparse.Namespace, strain: Any, tracking: TrackingConfig, reference: np.ndarray) -> tuple:
    """(placement, strain stage): the points as livedic run places them, the axial extensometer on P0."""
    from livedic.dic.correlation import snap_points
    from livedic.stream.session.config import PointsConfig
    from livedic.stream.session.parsing import parse_p0
    from livedic.stream.session.points import check_point_count, place_points, read_points_csv
    height, width = reference.shape[:2]
    if args.gauge_length >= height - tracking.subset:
        raise UsageError(f"--gauge-length {args.gauge_length:g} px does not fit the {width}x{height} image: its ends "
                         f"and their subsets need less than {height - tracking.subset} px along y")
    xy = read_points_csv(args.points) if args.points else None
    wanted = PointsConfig(points_file=args.points, xy=xy, step=args.step, n_points=args.n_points,
                          p0=parse_p0(args.p0), max_points=args.max_points, **PointsConfig.region_from_args(args))
    placement = place_points(reference, wanted, subset=tracking.subset)
    check_point_count(len(placement.points), wanted.max_points, how=wanted.how(placement.step))
    xs, ys = snap_points(placement.points)
    used = np.column_stack([xs, ys]).astype(np.float64)
    stage = strain.place(used, p0=used[0], roi=placement.bounds, step=placement.step, subset=tracking.subset,
                         image_size=(width, height))
    return placement, stage


def _track(tracking: TrackingConfig, reference: np.ndarray, points: np.ndarray, stage: Any,
           images: Sequence[np.ndarray]) -> tuple[np.ndarray, int]:
    """The axial extensometer's elongation reading (px, NaN where not ok) of each image, tracked in order, and
    the points not ok summed over the images."""
    from livedic.dic.strain.extensometer import AXIAL
    tracker = tracking.tracker(reference, points)
    axial = [e.name for e in stage.extensometers].index(AXIAL)
    readings = np.full(len(images), np.nan)
    lost = 0
    for k, image in enumerate(images):
        measured = tracker.track(image)
        lost += int(np.count_nonzero(~measured.ok))
        _, read = stage.compute(measured.u, measured.v, measured.ok)
        if read.ok[axial]:
            readings[k] = float(read.length_px[axial] - read.l0_px[axial])
    return readings, lost


def _entry(steps: KnownSteps, readings: np.ndarray, l0_px: float, scale: float | None,
           paths: Sequence[str]) -> dict[str, Any]:
    """The gauge length's verification entry: per step the known elongation, its readings and images."""
    from livedic.stream.export.report_verification import classified_entry
    px_per_um = scale / UM_PER_MM if scale else 0.0
    labels = [f"{value:g} um" if value else "0 (static/rigid)" for value in steps.values_um]
    entry = classified_entry([value * px_per_um for value in steps.values_um],
                             [readings[list(members)] for members in steps.members], l0_px, scale, labels=labels)
    for row, value, members in zip(entry["steps"], steps.values_um, steps.members):
        row.update(known_um=value, images=[paths[k] for k in members])
    return entry


def _document(args: argparse.Namespace, tracking: TrackingConfig, strain: Any, placement: Any, shape: tuple,
              paths: Sequence[str], known_um: Sequence[float], entry: dict[str, Any], lost: int,
              seconds: float) -> dict[str, Any]:
    """The verification file's content (the schema of ``livedic bench extensometer -o``)."""
    import platform
    from datetime import datetime, timezone

    from livedic.stream.export.report_verification import USER_FRAMES
    settings = {"source": USER_FRAMES, "reference": args.reference, "images": list(paths),
                "elongations_file": args.elongations, "elongations_um": [float(v) for v in known_um],
                "gauge_lengths_px": [args.gauge_length], "scale_px_per_mm": strain.px_per_mm,
                "calibration": args.calibration, "subset": tracking.subset, "step_px": placement.step,
                "points": len(placement.points), "p0": [float(v) for v in placement.points[0]],
                "search": tracking.search, "subpixel": tracking.subpixel,
                "reference_update": tracking.reference_update, "image": [shape[1], shape[0]],
                "end_fit": strain.axial_end_fit,
                "frames_per_step": [len(row["images"]) for row in entry["steps"]]}
    verdict = (f"class {entry['met_class']}" if entry["met_class"] else f"no class: {entry['reason_text']}")
    return {"settings": settings, "date": datetime.now(timezone.utc).isoformat(),
            "environment": {"cpu_count": os.cpu_count(), "machine": platform.machine()},
            "standard": "ISO 9513:2012 Table 2; in-situ known displacements as EN 4861:2020, on the user's frames",
            "gauge_lengths": [entry], "lost_points": lost, "seconds": seconds, "verdict": verdict}
