"""CAL.json: a camera calibration on disk (``livedic calibrate`` writes it; ``--calibration`` reads it).

The file is JSON: ``{"format": "livedic-calibration", "version": 1, "livedic": VERSION, ...}`` and the
body of ``CameraCalibration.to_dict`` (image size, camera matrix, distortion, per-image errors, target,
square, the specimen plane's scale). It is written whole or not at all (``AtomicFile``). Reading
checks the header and every field: a file that does not parse, a missing field or another format is
one ``CalibrationError`` line naming the file.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

from livedic.acquire.atomic_file import AtomicFile
from livedic.acquire.files.image_file import read_grey_image
from livedic.acquire.files.image_sequence import find_images
from livedic.dic.calibration import (DEFAULT_MAX_ERROR_PX, MIN_VIEWS, CalibrationError, CameraCalibration,
                                     Detection, NotFound, TargetSpec, calibrate, detect_target, parse_target,
                                     plane_scale)

FORMAT = "livedic-calibration"
VERSION = 1


def calibration_document(calibration: CameraCalibration) -> dict[str, Any]:
    """The whole file as a dict (what a session records in its metadata too)."""
    from livedic.acquire.recording.chunked_writer import software_version
    return {"format": FORMAT, "version": VERSION, "livedic": software_version(), **calibration.to_dict()}


def write_calibration(path: str | os.PathLike[str], calibration: CameraCalibration) -> None:
    """Write CAL.json atomically (a crash leaves the old file or none, never half of one)."""
    with AtomicFile(path) as out:
        out.write(json.dumps(calibration_document(calibration), indent=2) + "\n")
        out.commit()


def calibration_from_document(document: Any, source: str = "the calibration") -> CameraCalibration:
    """The calibration in a parsed CAL.json (or a session's recorded copy); CalibrationError if it is not one."""
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise CalibrationError(f"{source} is not a livedic calibration (no \"format\": \"{FORMAT}\"): "
                               "make one with livedic calibrate")
    if document.get("version") != VERSION:
        raise CalibrationError(f"{source} is a calibration of version {document.get('version')!r}; this livedic "
                               f"reads version {VERSION}: calibrate again with this livedic")
    try:
        return CameraCalibration.from_dict(document)
    except CalibrationError as error:
        raise CalibrationError(f"{source}: {error}") from None


def read_calibration(path: str | os.PathLike[str]) -> CameraCalibration:
    """Read and check CAL.json; CalibrationError (one line, naming the file) if it cannot be used."""
    name = os.fspath(path)
    try:
        with open(name, encoding="utf-8") as handle:
            document = json.load(handle)
    except FileNotFoundError:
        raise CalibrationError(f"calibration file {name} does not exist") from None
    except IsADirectoryError:
        raise CalibrationError(f"calibration file {name} is a folder: give the CAL.json file") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise CalibrationError(f"calibration file {name} does not parse as JSON ({error}): give a CAL.json "
                               "written by livedic calibrate") from None
    return calibration_from_document(document, f"calibration file {name}")


@dataclass(frozen=True)
class ImageOutcome:
    """One image's fate in ``calibrate_images``: its detection or why none."""

    name: str
    found: Detection | NotFound


def expand_images(arguments: Sequence[str]) -> list[str]:
    """Files, folders and globs -> image files (a folder or glob in natural order); CalibrationError if none."""
    names: list[str] = []
    for argument in arguments:
        if os.path.isfile(argument):
            names.append(argument)
            continue
        found = find_images(argument)
        if not found:
            raise CalibrationError(f"{argument}: no such image, and no PNG/TIFF image in that folder or glob")
        names.extend(found)
    return names


def calibrate_images(images: Sequence[str], target: str, square_mm: float, *, plane: str | None = None,
                     max_error_px: float = DEFAULT_MAX_ERROR_PX,
                     on_image: Callable[[ImageOutcome], object] | None = None) -> CameraCalibration:
    """Calibrate from target images on disk (each read, its target found, then ``dic.calibration.calibrate``).

    Images in which the target is not found are left out (``on_image`` hears of each); ``plane`` is an
    image of the target lying on the specimen plane, giving px/mm (it must show the target).

    Raises
    ------
    CalibrationError
        A bad target spec or square, images of different sizes, too few views, a fit above the bound,
        or a plane image without the target.
    """
    spec = _spec(target)
    if not (square_mm > 0.0 and square_mm < float("inf")):
        raise CalibrationError(f"--square {square_mm:g}: the target's square side must be a length > 0 in mm")
    size: tuple[int, int] | None = None
    first = ""
    found: list[tuple[str, Detection]] = []
    skipped: list[str] = []
    for name in images:
        image = _read(name)
        shape = (image.shape[1], image.shape[0])
        if size is None:
            size, first = shape, name
        elif shape != size:
            raise CalibrationError(f"{name} is {shape[0]}x{shape[1]} but {first} is {size[0]}x{size[1]}: every "
                                   "calibration image must come from the camera at the measurement's resolution")
        detection = detect_target(image, spec, square_mm)
        if on_image is not None:
            on_image(ImageOutcome(name, detection))
        if isinstance(detection, Detection):
            found.append((os.path.basename(name), detection))
        else:
            skipped.append(os.path.basename(name))
    if size is None:
        raise CalibrationError("no calibration image given")
    if len(found) < MIN_VIEWS:
        raise CalibrationError(f"the target {spec.text} was found in {len(found)} of {len(images)} image(s); a "
                               f"calibration needs at least {MIN_VIEWS} views at different tilts: check --target "
                               "(a chessboard counts inner corners: 10 x 7 squares is chessboard:9x6) and the images")
    calibration = calibrate(found, size, target=spec.text, square_mm=square_mm, max_error_px=max_error_px,
                            skipped=skipped)
    if plane is None:
        return calibration
    image = _read(plane)
    calibration.check_size(image.shape[1], image.shape[0], f"the plane image {plane}")
    detection = detect_target(image, spec, square_mm)
    if isinstance(detection, NotFound):
        raise CalibrationError(f"--plane {plane}: {detection.detail}: give an image of the target lying on the "
                               "specimen's surface")
    return replace(calibration, plane=plane_scale(calibration, os.path.basename(plane), detection))


def _spec(target: str) -> TargetSpec:
    try:
        return parse_target(target)
    except ValueError as error:
        raise CalibrationError(f"--target: {error}") from None


def _read(name: str) -> Any:
    try:
        return read_grey_image(name)[0]
    except ValueError as error:
        raise CalibrationError(str(error)) from None
