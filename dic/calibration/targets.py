"""Calibration targets: their text form, their corners in mm, and finding them in an image.

``chessboard:COLSxROWS`` counts INNER corners, as OpenCV does (a board of 10 x 7 squares is
``chessboard:9x6``). ``charuco:COLSxROWS[:DICT[:MARKER]]`` counts SQUARES; its ArUco markers are
``MARKER`` x the square (default 0.75) from dictionary ``DICT`` (default DICT_5X5_100, any
``cv2.aruco.DICT_*`` name). ``detect_target`` returns a ``Detection`` (image points, their corner ids
and the board's points in mm) or a ``NotFound`` with a typed reason.
"""

from __future__ import annotations

import enum
import re
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np

DEFAULT_CHARUCO_DICTIONARY = "DICT_5X5_100"
DEFAULT_MARKER_FRACTION = 0.75
# A ChArUco view with fewer corners than this does not constrain a homography well (OpenCV needs 4; 6 is safer).
MIN_CHARUCO_CORNERS = 6
_SIZE = re.compile(r"^(\d+)x(\d+)$")
_USAGE = ("write chessboard:COLSxROWS (inner corners, e.g. chessboard:9x6 for a board of 10 x 7 squares) or "
          "charuco:COLSxROWS[:DICT[:MARKER]] (squares, e.g. charuco:11x8:DICT_5X5_100:0.75)")


class NotFoundReason(enum.Enum):
    """Why no target was taken from an image."""

    NO_TARGET = "no target found"
    TOO_FEW_CORNERS = "too few corners seen"


@dataclass(frozen=True)
class NotFound:
    """No usable target in an image: the typed ``reason`` and a sentence for the user."""

    reason: NotFoundReason
    detail: str


@dataclass(frozen=True)
class TargetSpec:
    """A calibration target as ``parse_target`` reads it.

    Attributes
    ----------
    kind : {"chessboard", "charuco"}
    cols, rows : int
        Chessboard: inner corners per row and per column; ChArUco: squares.
    dictionary : str or None
        The ArUco dictionary's name (ChArUco only).
    marker_fraction : float or None
        Marker side / square side (ChArUco only).
    """

    kind: Literal["chessboard", "charuco"]
    cols: int
    rows: int
    dictionary: str | None = None
    marker_fraction: float | None = None

    @property
    def text(self) -> str:
        """The spec written back as the command line takes it."""
        if self.kind == "chessboard":
            return f"chessboard:{self.cols}x{self.rows}"
        return f"charuco:{self.cols}x{self.rows}:{self.dictionary}:{self.marker_fraction:g}"

    @property
    def inner_corners(self) -> tuple[int, int]:
        """(columns, rows) of the board's inner corners, the points a calibration uses."""
        if self.kind == "chessboard":
            return (self.cols, self.rows)
        return (self.cols - 1, self.rows - 1)

    def object_points(self, square_mm: float) -> np.ndarray:
        """The inner corners on the board (mm), shape (N, 3), z = 0, in the order of their ids."""
        if self.kind == "charuco":
            return np.asarray(self.charuco_board(square_mm).getChessboardCorners(), dtype=np.float64).reshape(-1, 3)
        cols, rows = self.inner_corners
        grid = np.zeros((rows * cols, 3))
        grid[:, 0] = np.tile(np.arange(cols), rows) * square_mm
        grid[:, 1] = np.repeat(np.arange(rows), cols) * square_mm
        return grid

    def charuco_board(self, square_mm: float) -> cv2.aruco.CharucoBoard:
        """OpenCV's board object of this ChArUco spec with squares of ``square_mm``."""
        if self.kind != "charuco":
            raise ValueError(f"{self.text} is not a ChArUco target")
        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, str(self.dictionary)))
        marker = float(self.marker_fraction or DEFAULT_MARKER_FRACTION) * square_mm
        return cv2.aruco.CharucoBoard((self.cols, self.rows), square_mm, marker, dictionary)


@dataclass(frozen=True)
class Detection:
    """A target found in one image.

    Attributes
    ----------
    image_points : ndarray, shape (N, 2)
        The corners in image pixels (distorted, as the camera saw them), float64.
    ids : ndarray of int, shape (N,)
        Which corner of ``TargetSpec.object_points`` each one is.
    object_points : ndarray, shape (N, 3)
        The same corners on the board (mm).
    """

    image_points: np.ndarray
    ids: np.ndarray
    object_points: np.ndarray


def parse_target(text: str) -> TargetSpec:
    """A ``TargetSpec`` from ``chessboard:COLSxROWS`` or ``charuco:COLSxROWS[:DICT[:MARKER]]``.

    Raises
    ------
    ValueError
        One line naming what is wrong and the form to write.
    """
    parts = str(text).strip().split(":")
    kind = parts[0].lower()
    if kind not in ("chessboard", "charuco") or len(parts) < 2:
        raise ValueError(f"target {text!r}: {_USAGE}")
    size = _SIZE.match(parts[1].lower())
    if not size:
        raise ValueError(f"target {text!r}: the size must be COLSxROWS, e.g. 9x6; {_USAGE}")
    cols, rows = int(size.group(1)), int(size.group(2))
    if kind == "chessboard":
        if len(parts) > 2:
            raise ValueError(f"target {text!r}: a chessboard takes only its size; {_USAGE}")
        if min(cols, rows) < 2:
            raise ValueError(f"target {text!r}: a chessboard needs at least 2 x 2 inner corners")
        return TargetSpec("chessboard", cols, rows)
    if min(cols, rows) < 3 or len(parts) > 4:
        raise ValueError(f"target {text!r}: a ChArUco board needs at least 3 x 3 squares; {_USAGE}")
    dictionary = parts[2].upper() if len(parts) > 2 and parts[2] else DEFAULT_CHARUCO_DICTIONARY
    if not dictionary.startswith("DICT_") or not hasattr(cv2.aruco, dictionary):
        raise ValueError(f"target {text!r}: unknown ArUco dictionary {dictionary!r} (e.g. DICT_5X5_100, "
                         "DICT_4X4_50, DICT_6X6_250)")
    try:
        fraction = float(parts[3]) if len(parts) > 3 else DEFAULT_MARKER_FRACTION
    except ValueError:
        fraction = float("nan")
    if not 0.1 <= fraction < 1.0:
        raise ValueError(f"target {text!r}: the marker size is a fraction of the square in 0.1..0.99, "
                         f"e.g. 0.75, got {parts[3]!r}")
    count = cols * rows // 2
    capacity = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary)).bytesList.shape[0]
    if count > capacity:
        raise ValueError(f"target {text!r}: {count} markers but {dictionary} has {capacity}: choose a larger "
                         "dictionary")
    return TargetSpec("charuco", cols, rows, dictionary, fraction)


def detect_target(image: np.ndarray, spec: TargetSpec, square_mm: float) -> Detection | NotFound:
    """Find ``spec``'s corners in a grey image (8 or 16 bit), to sub-pixel precision.

    A chessboard is found whole or not at all (``cv2.findChessboardCornersSB``, which is accurate
    without a separate ``cornerSubPix``); a ChArUco board may be seen in part
    (``cv2.aruco.CharucoDetector``), down to ``MIN_CHARUCO_CORNERS`` corners.
    """
    grey = _as_8bit(image)
    objects = spec.object_points(square_mm)
    if spec.kind == "chessboard":
        found, corners = cv2.findChessboardCornersSB(grey, spec.inner_corners, flags=cv2.CALIB_CB_ACCURACY)
        if not found:
            cols, rows = spec.inner_corners
            return NotFound(NotFoundReason.NO_TARGET, f"no chessboard of {cols}x{rows} inner corners found")
        points = corners.reshape(-1, 2).astype(np.float64)
        ids = np.arange(points.shape[0])
        return Detection(points, ids, objects[ids])
    detector = cv2.aruco.CharucoDetector(spec.charuco_board(square_mm))
    corners, found_ids, _, _ = detector.detectBoard(grey)
    count = 0 if found_ids is None else len(found_ids)
    if count == 0:
        return NotFound(NotFoundReason.NO_TARGET, f"no ChArUco board {spec.text} found")
    if count < MIN_CHARUCO_CORNERS:
        return NotFound(NotFoundReason.TOO_FEW_CORNERS,
                        f"only {count} ChArUco corners seen (at least {MIN_CHARUCO_CORNERS} needed)")
    ids = np.asarray(found_ids, dtype=np.int64).ravel()
    return Detection(np.asarray(corners, dtype=np.float64).reshape(-1, 2), ids, objects[ids])


def _as_8bit(image: np.ndarray) -> np.ndarray:
    """The detectors take 8-bit images: deeper ones are scaled by their own maximum."""
    if image.dtype == np.uint8:
        return image
    top = float(np.max(image)) or 1.0
    return np.clip(np.rint(image.astype(np.float64) * (255.0 / top)), 0, 255).astype(np.uint8)
