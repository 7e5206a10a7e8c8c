"""CAL.json: a camera calibration on disk (``livedic calibrate`` writes it; ``--calibration`` reads it).

The file is JSON: ``{"format": "livedic-calibration", "version": 1, "livedic": VERSION, ...}`` and the
body of ``CameraCalibration.to_dict`` (image size, camera matrix, distortion, per-image errors, target,
square, the specimen plane's scale). A stereo rig's file has the same header and the body of
``StereoCalibration.to_dict``: ``"stereo": true``, each camera's body under "left" and "right", R, T and the
per-pair errors. It is written whole or not at all (``AtomicFile``). Reading checks the header and every
field: a file that does not parse, a missing field, another format, or a stereo file where one camera's is
expected (and the reverse) is one ``CalibrationError`` line naming the file.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any, TypeVar

from livedic.acquire.atomic_file import AtomicFile
from livedic.acquire.files.image_file import read_grey_image, read_same_size_images
from livedic.acquire.files.image_sequence import find_images
from livedic.dic.calibration import (DEFAULT_MAX_ERROR_PX, DEFAULT_UNCERTAINTY_BOUNDS, MIN_VIEWS, CalibrationError,
                                     CameraCalibration, Detection, NotFound, StereoCalibration, TargetPair, TargetSpec,
                                     UncertaintyBounds, calibrate, calibrate_stereo, detect_target, parse_target,
                                     plane_scale)

FORMAT = "livedic-calibration"
VERSION = 1
Parsed = TypeVar("Parsed", CameraCalibration, StereoCalibration)


def calibration_document(calibration: CameraCalibration | StereoCalibration) -> dict[str, Any]:
    """The whole file as a dict (what a session records in its metadata too), of one camera or a stereo rig."""
    from livedic.acquire.recording.chunked_writer import software_version
    return {"format": FORMAT, "version": VERSION, "livedic": software_version(), **calibration.to_dict()}


def write_calibration(path: str | os.PathLike[str], calibration: CameraCalibration | StereoCalibration) -> None:
    """Write CAL.json atomically (a crash leaves the old file or none, never half of one)."""
    with AtomicFile(path) as out:
        out.write(json.dumps(calibration_document(calibration), indent=2) + "\n")
        out.commit()


def calibration_from_document(document: Any, source: str = "the calibration") -> CameraCalibration:
    """The one-camera calibration in a parsed CAL.json (or a session's recorded copy); CalibrationError if it is
    not one (a stereo rig's included)."""
    _check_header(document, source, stereo=False)
    return _parsed(CameraCalibration.from_dict, document, source)


def stereo_calibration_from_document(document: Any, source: str = "the calibration") -> StereoCalibration:
    """The stereo rig in a parsed CAL.json; CalibrationError if it is not one (a one-camera file included)."""
    _check_header(document, source, stereo=True)
    return _parsed(StereoCalibration.from_dict, document, source)


def _check_header(document: Any, source: str, *, stereo: bool) -> None:
    """CalibrationError unless ``document`` is a calibration of this version, of a stereo rig or of one camera."""
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise CalibrationError(f"{source} is not a livedic calibration (no \"format\": \"{FORMAT}\"): "
                               "make one with livedic calibrate")
    if document.get("version") != VERSION:
        raise CalibrationError(f"{source} is a calibration of version {document.get('version')!r}; this livedic "
                               f"reads version {VERSION}: calibrate again with this livedic")
    if bool(document.get("stereo")) == stereo:
        return
    if stereo:
        raise CalibrationError(f"{source} is a one-camera calibration: a stereo source needs a stereo one (livedic "
                               "calibrate --left IMAGES --right IMAGES ...)")
    raise CalibrationError(f"{source} is a stereo calibration (two cameras): use it with a stereo source "
                           "(--source stereo:LEFT,RIGHT), or calibrate the one camera alone")


def _parsed(from_dict: Callable[[dict[str, Any]], Parsed], document: dict[str, Any], source: str) -> Parsed:
    """``from_dict(document)``, its CalibrationError naming ``source``."""
    try:
        return from_dict(document)
    except CalibrationError as error:
        raise CalibrationError(f"{source}: {error}") from None


def read_calibration(path: str | os.PathLike[str]) -> CameraCalibration:
    """Read and check a one camera's CAL.json; CalibrationError (one line, naming the file) if it cannot be used."""
    name = os.fspath(path)
    return calibration_from_document(_read_document(name), f"calibration file {name}")


def read_stereo_calibration(path: str | os.PathLike[str]) -> StereoCalibration:
    """Read and check a stereo rig's CAL.json; CalibrationError (one line, naming the file) if it cannot be used."""
    name = os.fspath(path)
    return stereo_calibration_from_document(_read_document(name), f"calibration file {name}")


def read_any_calibration(path: str | os.PathLike[str]) -> CameraCalibration | StereoCalibration:
    """Read a CAL.json of either kind: a stereo rig's (``"stereo": true``) or one camera's; CalibrationError
    (one line, naming the file) if it cannot be used."""
    name = os.fspath(path)
    document = _read_document(name)
    if isinstance(document, dict) and document.get("stereo"):
        return stereo_calibration_from_document(document, f"calibration file {name}")
    return calibration_from_document(document, f"calibration file {name}")


def _read_document(name: str) -> Any:
    """The parsed JSON of calibration file ``name``; CalibrationError when it is missing or does not parse."""
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
    return document


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
                     bounds: UncertaintyBounds = DEFAULT_UNCERTAINTY_BOUNDS,
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
                            skipped=skipped, bounds=bounds)
    if plane is None:
        return calibration
    image = _read(plane)
    calibration.check_size(image.shape[1], image.shape[0], f"the plane image {plane}")
    detection = detect_target(image, spec, square_mm)
    if isinstance(detection, NotFound):
        raise CalibrationError(f"--plane {plane}: {detection.detail}: give an image of the target lying on the "
                               "specimen's surface")
    return replace(calibration, plane=plane_scale(calibration, os.path.basename(plane), detection))


@dataclass(frozen=True)
class PairOutcome:
    """One image pair's fate in ``calibrate_image_pairs``: what was found in each view."""

    left: ImageOutcome
    right: ImageOutcome


def check_image_pairs(left_images: Sequence[str], right_images: Sequence[str], of: str) -> None:
    """CalibrationError unless both cameras give as many images: the i-th left and the i-th right (sorted) are one
    pair, images ``of`` the same poses or moments."""
    if len(left_images) != len(right_images):
        raise CalibrationError(f"--left gives {len(left_images)} image(s) but --right {len(right_images)}: each "
                               "left image pairs with the right image of the same place in sorted order, so give "
                               f"both cameras' images of the same {of}")


def calibrate_image_pairs(left_images: Sequence[str], right_images: Sequence[str], target: str, square_mm: float, *,
                          max_error_px: float = DEFAULT_MAX_ERROR_PX,
                          bounds: UncertaintyBounds = DEFAULT_UNCERTAINTY_BOUNDS,
                          on_pair: Callable[[PairOutcome], object] | None = None) -> StereoCalibration:
    """Calibrate a stereo rig from target images on disk: the i-th left image and the i-th right image are one
    pair (taken at the same moment); each read, its target found, then ``calibrate_stereo``.

    Raises
    ------
    CalibrationError
        Lists of different lengths, images of one camera of different sizes, a bad target spec or square, too few
        pairs showing the target in both views, or a fit above the bound.
    """
    spec = _spec(target)
    if not (square_mm > 0.0 and square_mm < float("inf")):
        raise CalibrationError(f"--square {square_mm:g}: the target's square side must be a length > 0 in mm")
    check_image_pairs(left_images, right_images, "poses")
    if not left_images:
        raise CalibrationError("no calibration image given")
    try:
        lefts = read_same_size_images(list(left_images), "the left camera's calibration images")[0]
        rights = read_same_size_images(list(right_images), "the right camera's calibration images")[0]
    except ValueError as error:
        raise CalibrationError(str(error)) from None
    pairs = []
    for left_name, right_name, left, right in zip(left_images, right_images, lefts, rights):
        outcome = PairOutcome(ImageOutcome(os.path.basename(left_name), detect_target(left, spec, square_mm)),
                              ImageOutcome(os.path.basename(right_name), detect_target(right, spec, square_mm)))
        if on_pair is not None:
            on_pair(outcome)
        pairs.append(TargetPair(outcome.left.name, outcome.right.name, _found(outcome.left), _found(outcome.right)))
    both = sum(pair.left_found is not None and pair.right_found is not None for pair in pairs)
    if both < MIN_VIEWS:
        raise CalibrationError(f"the target {spec.text} was found in both views of {both} of {len(pairs)} pair(s); "
                               f"a stereo calibration needs at least {MIN_VIEWS} pairs at different tilts: check "
                               "--target (a chessboard counts inner corners: 10 x 7 squares is chessboard:9x6) and "
                               "that both cameras see the whole board")
    size = (lefts[0].shape[1], lefts[0].shape[0]), (rights[0].shape[1], rights[0].shape[0])
    return calibrate_stereo(pairs, *size, spec=spec, square_mm=square_mm, max_error_px=max_error_px, bounds=bounds)


def _found(outcome: ImageOutcome) -> Detection | None:
    return outcome.found if isinstance(outcome.found, Detection) else None


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
