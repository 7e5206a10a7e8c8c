"""Strain and extensometers of a stereo session: on the specimen's surface and in space, from the 3D points.

``StereoStrainStage`` is the ``StrainStage`` of a stereo session. It is placed like the 2D one, on the left
view's reference points (the strain windows' neighbours, the extensometers' ends and bands, in left image px),
and set up on the reference pair's 3D points when the first result (the reference's) arrives. Per frame it
reads the ``StereoMeasurement``'s 3D points, not the left view's displacements:

* strain in each point's tangent plane (``dic.stereo.surface_strain``), always Green-Lagrange
  (``SURFACE_MEASURE``: a rigid turn of the specimen in space reads exactly zero; the small-strain measure would
  read a 1 degree turn as -1.5e-4);
* each extensometer's ends fitted in X, Y, Z over their bands and the length between them in space, in mm
  (``dic.stereo.extensometer``): what a 2D length reads of out-of-plane motion is gone.

Where the gauge length is given in mm the ends are placed with the rig's nominal px/mm at its working distance
(the left camera's focal length over that distance); the L0 reported is the one measured in space. The guide:
docs/guide/stereo.md.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from livedic.dic.calibration import StereoCalibration
from livedic.dic.stereo import SURFACE_MEASURE, SurfaceWindow, surface_strain, surface_window, working_distance
from livedic.dic.stereo.extensometer import read_extensometers_3d
from livedic.stream.pipeline.frame_result import FrameResult
from livedic.stream.stages.strain import StrainConfig, StrainStage


def nominal_px_per_mm(calibration: StereoCalibration) -> float:
    """The left view's px per mm on a specimen facing it at the rig's working distance (placement only)."""
    return float(calibration.left.camera_matrix[0, 0]) / working_distance(calibration)


def stereo_strain_config(config: StrainConfig, calibration: StereoCalibration) -> StrainConfig:
    """``config`` for a stereo session: the rig's nominal scale where none was given, no 2D calibration."""
    scale = config.scale if config.scale is not None else nominal_px_per_mm(calibration)
    return replace(config, scale=scale, calibration=None, measure=SURFACE_MEASURE)


@dataclass
class StereoStrainStage(StrainStage):
    """The strain stage of a stereo session (module notes)."""

    surface: SurfaceWindow | None = None
    reference_xyz: np.ndarray | None = None
    reference_ok: np.ndarray | None = None

    @classmethod
    def of(cls, stage: StrainStage) -> StereoStrainStage:
        """The stereo stage on the same placement as ``stage`` (``StrainConfig.place``'s)."""
        return cls(stage.config, stage.points, stage.windows, stage.placed, ideal_points=stage.ideal_points)

    def _set_up(self, points: Any) -> None:
        """The reference pair's 3D points and each point's tangent frame (from the first, reference, result)."""
        self.reference_xyz = np.array(points.xyz, dtype=np.float64)
        self.reference_ok = np.array(points.ok, dtype=bool)
        self.surface = surface_window(self.points, self.reference_xyz, window=self.windows.window,
                                      step=self.windows.step, subset=self.windows.subset)

    def on_frame(self, result: FrameResult) -> None:
        """The frame's surface strain and 3D extensometer readings into ``result``."""
        started = time.perf_counter_ns()
        if result.fracture is not None:
            self.add_fracture(result.fracture)
        points = getattr(result.measurement, "points")      # a StereoMeasurement's 3D points
        if self.surface is None:
            self._set_up(points)
        assert self.surface is not None and self.reference_xyz is not None and self.reference_ok is not None
        strain = surface_strain(self.surface, self.reference_xyz, points.xyz, points.ok, measure=SURFACE_MEASURE)
        middle = time.perf_counter_ns()
        readings = read_extensometers_3d(self.placed, self.points, self.reference_xyz, self.reference_ok, points.xyz,
                                         points.ok, point_labels=self.point_labels, end_labels=self.end_labels)
        self.last_timings = {"strain": middle - started, "extensometers": time.perf_counter_ns() - middle}
        self.seconds.append((time.perf_counter_ns() - started) / 1e9)
        result.strain, result.extensometers = strain, readings
        self.last_strain, self.last_readings = strain, readings

    @property
    def vsg_mm(self) -> float | None:
        return None if self.surface is None else self.surface.vsg_mm

    def describe(self) -> str:
        text = (f"strain: on the specimen's surface (stereo), {SURFACE_MEASURE}, window {self.windows.window} points "
                f"x step {self.windows.step:g} px + subset {self.windows.subset} = VSG {self.vsg_px:.0f} px")
        if self.extensometers:
            text += "; extensometers in space " + ", ".join(
                f"{e.name} ~{e.length_px / self.config.px_per_mm:.1f} mm ({e.end_fit} ends)" for e in self.extensometers)
        return text

    def summary(self) -> dict[str, Any]:
        readings = self.last_readings
        final = {}
        if readings is not None:
            for i, name in enumerate(readings.names):
                final[name] = {"L0_px": None, "L0_mm": float(readings.l0_mm[i]), "L_px": None,
                               "L_mm": float(readings.length_mm[i]), "eng_strain": float(readings.eng_strain[i]),
                               "true_strain": float(readings.true_strain[i]), "ok": bool(readings.ok[i]),
                               "error_max_vs_truth": self.truth_errors.get(name)}
        return {"strain_measure": SURFACE_MEASURE, "strain_window": self.windows.window, "vsg_px": self.vsg_px,
                "vsg_mm": self.vsg_mm, "strain_ms_p50": self.ms_per_frame(50), "strain_ms_p99": self.ms_per_frame(99),
                "extensometers": final, "in_space": True}
