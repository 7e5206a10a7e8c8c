"""The points of a replay: the recorded ones, or rebuilt from the point options given (``PointOptions``).

What the user did not give comes from the session metadata (region, step, points wanted, P0), so a
rebuilt grid is the one ``livedic run`` would place with those options.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from livedic.stream.session.config import DEFAULT_POINTS, PointsConfig
from livedic.stream.session.parsing import ROI_AUTO, ROI_FULL, parse_exclusion, parse_p0, parse_roi, read_mask
from livedic.stream.session.points import place_points, read_points_csv

from livedic.stream.replay.parameters import _recorded_value, run_defaults


@dataclass
class PointOptions:
    """The user's point options (None = not given)."""
    roi: str | None = None
    points: str | None = None
    step: int | None = None
    n_points: int | None = None
    p0: str | None = None
    mask: str | None = None
    exclude: tuple[str, ...] | None = None

    @property
    def given(self) -> bool:
        return any(value is not None for value in (self.roi, self.points, self.step, self.n_points, self.p0,
                                                   self.mask, self.exclude))

    @property
    def region_given(self) -> bool:
        return any(value is not None for value in (self.roi, self.mask, self.exclude))

    def region(self) -> dict[str, Any]:
        """``PointsConfig``'s region fields from what was given (``PointsConfig.region_from_args``)."""
        return PointsConfig.region_from_args(self)

    def check(self) -> None:
        """ValueError (one line) for a bad option: ``PointsConfig``'s checks, on what was given."""
        PointsConfig(step=self.step, n_points=self.n_points if self.n_points is not None else DEFAULT_POINTS,
                     p0=parse_p0(self.p0), **self.region())


def _list_of_numbers(value: object, count: int) -> list[float] | None:
    if isinstance(value, (list, tuple)) and len(value) == count and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value):
        return [float(v) for v in value]
    return None


def recorded_region(metadata: Mapping[str, Any]) -> dict[str, Any]:
    """The region a recording's points were placed in, as ``PointsConfig`` fields (``roi``, ``exclude``).

    ``region`` (recordings since masks) says how; older ones give ``roi`` as X,Y,W,H or "full image".
    A recorded mask file is read again when it is still there, else its region's bounding box is used.
    """
    region: dict[str, Any] = metadata["region"] if isinstance(metadata.get("region"), dict) else {}
    exclude = tuple(parse_exclusion(text) for text in region.get("exclude") or ())
    placed_by = region.get("placed_by")
    if placed_by == "specimen":
        return {"roi": ROI_AUTO, "exclude": exclude}
    if placed_by == "given_region":
        fields: dict[str, Any] = {"roi": parse_roi(region["roi"]) if region.get("roi") else None, "exclude": exclude}
        mask_file = region.get("mask")
        if mask_file and os.path.exists(mask_file):
            fields.update(mask=read_mask(mask_file), mask_file=mask_file)
        elif mask_file and fields["roi"] is None:
            bounds = _list_of_numbers(region.get("bounds"), 4)
            fields["roi"] = tuple(int(v) for v in bounds) if bounds else None
        return fields
    recorded_roi = _list_of_numbers(metadata.get("roi"), 4)
    if recorded_roi:
        return {"roi": tuple(int(v) for v in recorded_roi), "exclude": exclude}
    return {"roi": ROI_FULL, "exclude": exclude}


def replay_points_config(metadata: Mapping[str, Any], options: PointOptions,
                         recorded_xy: np.ndarray | None) -> PointsConfig:
    """The points to rebuild (``PointsConfig``): the options given, the rest from the session metadata.

    What the user did not give comes from the session metadata (region, step, points
    wanted, P0); a recording made from a points file keeps its recorded points.
    """
    defaults = run_defaults()
    given_points = points_file = None
    if options.points is not None:
        given_points, points_file = read_points_csv(options.points), options.points
    elif not options.region_given and options.step is None and options.n_points is None \
            and metadata.get("points_file") not in (None, ""):
        if recorded_xy is None:
            raise ValueError(f"the recording tracked points from {metadata['points_file']}: give --points FILE.csv")
        given_points, points_file = recorded_xy, str(metadata["points_file"])
    region = options.region() if options.region_given else recorded_region(metadata)
    if options.step is not None:
        step = options.step
    elif options.region_given or options.n_points is not None:
        step = None
    else:
        step = _recorded_value("subset", metadata.get("step"))     # an int or None (then from n_points)
    n_points = options.n_points
    if n_points is None:
        n_points = _recorded_value("subset", metadata.get("n_points_wanted")) or defaults["n_points"]
    p0 = parse_p0(options.p0) if options.p0 is not None else _list_of_numbers(metadata.get("p0"), 2)
    return PointsConfig(points_file=points_file, xy=given_points, step=step, n_points=n_points, p0=p0, **region)


def build_replay_points(image: np.ndarray, metadata: Mapping[str, Any], subset: int, options: PointOptions,
                        recorded_xy: np.ndarray | None) -> np.ndarray:
    """Points (P0 first) for ``options`` given on the command line, as ``livedic run`` builds them.

    See ``replay_points_config``. A recording that does not give P0 as a point (older
    ones say "ROI centre") gets it placed on the reference ``image`` as ``livedic run``
    places it now.
    """
    wanted = replay_points_config(metadata, options, recorded_xy)
    return place_points(image, wanted, subset=subset).points
