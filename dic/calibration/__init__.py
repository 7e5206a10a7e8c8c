"""Camera calibration: calibration targets, the camera model (intrinsics, lens distortion, the specimen
plane's scale) and its solution from target images with OpenCV. Pure functions on arrays, no file I/O
(the CAL.json file: ``livedic.acquire.calibration``; the guide: docs/guide/calibration.md)."""

from livedic.dic.calibration.camera import (CalibrationError, CameraCalibration, ImageFit, PlaneFrame, PlaneScale,
                                            distort_points, image_points, plane_points, undistort_points)
from livedic.dic.calibration.determinacy import DEFAULT_UNCERTAINTY_BOUNDS, UncertaintyBounds
from livedic.dic.calibration.solve import (DEFAULT_MAX_ERROR_PX, MIN_VIEWS, CalibrationRefused, calibrate,
                                           plane_from_homography, plane_scale)
from livedic.dic.calibration.stereo import PairFit, StereoCalibration
from livedic.dic.calibration.stereo_solve import DEFAULT_STEREO_FLAGS, TargetPair, calibrate_stereo, match_pair
from livedic.dic.calibration.targets import (Detection, NotFound, NotFoundReason, TargetSpec, detect_target,
                                             parse_target)

__all__ = ["CalibrationError", "CalibrationRefused", "CameraCalibration", "DEFAULT_MAX_ERROR_PX",
           "DEFAULT_STEREO_FLAGS", "DEFAULT_UNCERTAINTY_BOUNDS", "Detection", "ImageFit", "MIN_VIEWS", "NotFound",
           "NotFoundReason", "PairFit", "PlaneFrame", "PlaneScale", "StereoCalibration", "TargetPair", "TargetSpec",
           "UncertaintyBounds", "calibrate", "calibrate_stereo", "detect_target", "distort_points", "image_points",
           "match_pair", "parse_target", "plane_from_homography", "plane_points", "plane_scale", "undistort_points"]
