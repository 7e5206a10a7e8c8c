"""The report's parameter tables, as the iDICs Good Practices Guide for DIC (2018, section 5) asks a DIC result to
state them: the hardware (camera, image, rate, exposure, scale) and the analysis (software, subset, step, shape
function, interpolant, criterion, search, pre-filter, strain method, window, VSG, strain measure, reference
updates), read from a recording's session metadata.

Each table is a list of ``Row`` (a key for ``report.json``, a label for people, the value as data and as text);
a value the recording does not hold is ``None`` and reads "not recorded", never a guess. docs/guide/tensile-test.md
shows the tables.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

NOT_RECORDED = "not recorded"
MEASURED = ("ok", "spatial_only")     # dic.noise_floor.NoiseFloorStatus values that carry numbers


@dataclass(frozen=True)
class Row:
    """One parameter of a report table: ``key`` in report.json, ``label`` and ``text`` in report.md."""
    key: str
    label: str
    value: Any
    text: str


def _row(key: str, label: str, value: Any, unit: str = "", text: str | None = None) -> Row:
    if text is None:
        text = NOT_RECORDED if value is None else (f"{value:g}" if isinstance(value, float) else str(value))
        if value is not None and unit:
            text += f" {unit}"
    return Row(key, label, value, text)


def _size(value: Any) -> list[int] | None:
    if isinstance(value, Sequence) and len(value) == 2 and all(isinstance(v, (int, float)) for v in value):
        return [int(value[0]), int(value[1])]
    return None


def _size_text(size: list[int] | None) -> str | None:
    return None if size is None else f"{size[0]} x {size[1]} px"


def camera_description(settings: Mapping[str, Any]) -> tuple[str, str | None]:
    """(what made the images, its serial number or None) from a source's recorded settings."""
    scheme = settings.get("source")
    if settings.get("vendor") or scheme in ("aravis", "opencv"):
        name = " ".join(str(settings[k]) for k in ("vendor", "model") if settings.get(k)) or str(scheme)
        return name, (str(settings["serial"]) if settings.get("serial") else None)
    uri = str(settings.get("uri") or "")
    if uri.startswith("synthetic:"):
        return f"livedic simulator ({uri.split('?')[0]}): rendered images with exact truth, no camera", None
    return (f"images from {uri}" if uri else NOT_RECORDED), None


def calibration_description(calibration: Mapping[str, Any]) -> str:
    """One line on a recorded calibration (CAL.json's fields): target, views, reprojection error, focal length,
    distortion, the specimen plane's scale and tilt."""
    matrix = calibration.get("camera_matrix") or [[float("nan")] * 3] * 2
    k = calibration.get("dist_coeffs") or []
    plane = calibration.get("plane") or {}
    text = (f"{calibration.get('target', 'target')} ({calibration.get('square_mm', '?')} mm squares), "
            f"{len(calibration.get('images') or [])} views, reprojection RMS {calibration.get('rms_px', float('nan')):.3f} "
            f"px; fx {matrix[0][0]:.1f}, fy {matrix[1][1]:.1f} px")
    if k:
        text += ", k1 " + f"{k[0]:.4g}" + (f", k2 {k[1]:.4g}" if len(k) > 1 else "")
    if plane:
        text += f"; specimen plane tilted {plane.get('tilt_deg', float('nan')):.1f} deg"
    return text + "; lens distortion removed before strain"


def hardware_rows(session: Mapping[str, Any], *, calibration: Mapping[str, Any] | None = None,
                  scale: tuple[float | None, str | None] | None = None) -> list[Row]:
    """The hardware table: camera and serial, sensor and image size, bit depth, frame rate, exposure, the
    calibration and the scale on the specimen plane (``scale``: (px/mm, where it comes from), default the
    session's ``--scale``)."""
    settings = session.get("source_settings") or {}
    left_view, right_view = settings.get("left"), settings.get("right")
    if settings.get("source") == "stereo" and isinstance(left_view, Mapping) and isinstance(right_view, Mapping):
        (left, left_serial), (right, right_serial) = camera_description(left_view), camera_description(right_view)
        camera = f"two cameras (stereo): left {left}; right {right}"
        serial = f"left {left_serial}, right {right_serial}" if left_serial or right_serial else None
        settings = {**settings, **left_view}          # the image settings: the left camera's (both views alike)
    else:
        camera, serial = camera_description(settings)
    image = _size(session.get("frame_size")) or _size([settings.get("width"), settings.get("height")])
    sensor = _size(settings.get("sensor_size"))
    bit = settings.get("bit_depth", settings.get("bit"))
    fps = settings.get("frame_rate", settings.get("fps"))
    exposure = settings.get("exposure_us")
    px_per_mm, origin = scale if scale is not None else (session.get("scale_px_per_mm"), None)
    rig = _stereo_rig_text(session)
    if rig is not None:
        calibration, calibration_text = session.get("stereo"), rig
        px_per_mm, origin = None, None
    elif calibration:
        calibration_text = calibration_description(calibration)
    else:
        calibration_text = "none: lens distortion not corrected"
    return [
        _row("camera", "camera", camera),
        _row("serial", "serial number", serial, text=serial or "n/a"),
        _row("sensor_size_px", "sensor size", sensor, text=_size_text(sensor) or NOT_RECORDED),
        _row("image_size_px", "image size", image, text=_size_text(image) or NOT_RECORDED),
        _row("bit_depth", "bit depth", bit, "bit"),
        _row("frame_rate_fps", "frame rate", fps, "fps"),
        _row("exposure_us", "exposure", exposure, "us"),
        _row("calibration", "calibration", calibration or None, text=calibration_text),
        _row("scale_px_per_mm", "scale on the specimen plane", px_per_mm,
             text=(f"{px_per_mm:g} px/mm" + (f" ({origin})" if origin else "")) if px_per_mm
             else "none needed: lengths measured in space, in mm (stereo)" if rig is not None
             else "none: lengths in px only"),
    ]


def _stereo_rig_text(session: Mapping[str, Any]) -> str | None:
    """One line on a stereo session's rig (its metadata's ``stereo``): baseline, angle, where its calibration came
    from and its reprojection RMS; None for one camera."""
    stereo = session.get("stereo")
    if not isinstance(stereo, Mapping) or not isinstance(stereo.get("calibration"), Mapping):
        return None
    rig = stereo["calibration"]
    pairs = rig.get("pairs") or []
    fit = f", reprojection RMS {rig.get('rms_px', float('nan')):.3f} px over {len(pairs)} target pairs" if pairs else ""
    return (f"stereo rig: baseline {rig.get('baseline_mm', float('nan')):.1f} mm, {rig.get('angle_deg', float('nan')):.1f} "
            f"degrees between the cameras; calibration: {stereo.get('calibration_from') or NOT_RECORDED}{fit}; "
            f"lens distortion removed before triangulation")


def analysis_rows(session: Mapping[str, Any]) -> list[Row]:
    """The analysis table: software, subset, step, shape function, interpolant (of the recorded
    ``--interpolation``), correlation criterion, search,
    pre-filter, strain method, window, VSG, strain measure and reference updates."""
    from livedic.dic.subpixel.method import METHODS
    method = METHODS.get(str(session.get("subpixel")))
    version = session.get("software_version")
    step = session.get("grid_step") or session.get("step")
    window = session.get("strain_window")
    vsg = session.get("vsg_px")
    strain_method = "pointwise least squares: a plane fitted to u and v over the window (Pan et al. 2009)"
    measure = session.get("strain_measure")
    stereo: list[Row] = []
    if _stereo_rig_text(session) is not None:
        from livedic.dic.stereo import SURFACE_MEASURE
        strain_method = ("on the specimen's surface: planes fitted to U, V, W over the window in each point's tangent "
                         "plane (dic.stereo.surface_strain); extensometers' ends fitted in X, Y, Z")
        measure = f"{SURFACE_MEASURE} (Green-Lagrange, on the surface: a stereo session's)"
        stereo = [_row("stereo_method", "stereo matching and triangulation",
                       "left -> right on the reference pair: an epipolar ZNCC scan seeding a second-order IC-GN warp "
                       "(dic.stereo.match_stereo); both views tracked from their references; optimal triangulation "
                       "(Hartley-Sturm correction, dic.stereo.triangulate)")]
    return [
        _row("software", "DIC software", f"livedic {version}" if version else None),
        _row("subset_px", "subset size", session.get("subset"), "px (square)"),
        _row("step_px", "step (grid spacing)", step, "px"),
        _row("subpixel", "sub-pixel method", session.get("subpixel")),
        _row("shape_function", "subset shape function", method.shape_function if method else None),
        _interpolant_row(method, session.get("interpolation", "bspline3")),     # recorded before it existed: cubic
        _row("criterion", "correlation criterion", method.criterion if method else None),
        _row("search", "initial guess (integer search)", session.get("search")),
        _prefilter_row(session.get("prefilter", "none")),   # recorded before the option existed: none applied
        *stereo,
        _row("strain_method", "strain calculation", strain_method),
        _row("strain_window_points", "strain window", window, "points a side"),
        _row("vsg_px", "virtual strain gauge (VSG)", vsg, "px"),
        _row("strain_measure", "strain measure", measure),
        _row("reference_update", "reference updates", session.get("reference_update")),
    ]


def _interpolant_row(method: Any, recorded: Any) -> Row:
    """The interpolant the method sampled with (``SubpixelMethod.interpolant_for`` the recorded ``--interpolation``)."""
    if method is None:
        return _row("interpolant", "grey-level interpolant", None)
    try:
        text = method.interpolant_for(recorded)
    except ValueError:
        text = f"{method.interpolant} ({recorded}?)"   # a value this version does not know: not reinterpreted
    return _row("interpolant", "grey-level interpolant", text)


def _prefilter_row(recorded: Any) -> Row:
    """The pre-filter as recorded (``--prefilter``'s text), described (``dic.image_filter.Prefilter.describe``)."""
    from livedic.dic.image_filter import Prefilter
    try:
        text = Prefilter.parse(recorded).describe()
    except ValueError:
        text = str(recorded)        # a value this version does not know: shown as recorded, not reinterpreted
    return _row("prefilter", "image pre-filter", recorded, text=text)


def rows_json(rows: Sequence[Row]) -> dict[str, Any]:
    """A table as ``report.json`` holds it: key -> value (data; None where not recorded)."""
    return {row.key: row.value for row in rows}


def rows_markdown(rows: Sequence[Row], heading: str) -> list[str]:
    """A table as ``report.md`` lines: a heading and a two-column table."""
    lines = [f"## {heading}", "", "| parameter | value |", "|---|---|"]
    lines += [f"| {row.label} | {_cell(row.text)} |" for row in rows]
    return lines + [""]


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _floor_item(noise_floor: Mapping[str, Any] | None, quantity: str, unit: str) -> Mapping[str, Any] | None:
    for item in (noise_floor or {}).get("table", ()):
        # one static frame (spatial_only) still measures the spatial SD; a missing value reads as not measured
        if item.get("quantity") == quantity and item.get("unit") == unit and item.get("status") in MEASURED:
            return item
    return None


def _sd_text(item: Mapping[str, Any] | None, digits: int, unit: str, key: str = "spatial_sd") -> str | None:
    if item is None or item.get(key) is None:
        return None
    return f"{item[key]:.{digits}f} {unit}"


def performance_rows(session: Mapping[str, Any], *, noise_floor: Mapping[str, Any] | None,
                     verification: Mapping[str, Any] | None, scale: float | None) -> list[Row]:
    """The measured-performance table (the iDICs guide's): spatial resolution (the subset for displacement, the
    VSG for strain), the noise floor of the displacements and strains on the session's static frames (spatial
    SD; ``stream.stages.noise_floor``), the axial extensometer's noise, and its ISO 9513 class as verified."""
    subset, vsg = session.get("subset"), session.get("vsg_px")

    def length(px: Any) -> str | None:
        if px is None:
            return None
        return f"{px:g} px" + (f" = {px / scale:.3f} mm" if scale else "")

    rows = [_row("displacement_resolution_px", "spatial resolution, displacement (subset)", subset,
                 text=length(subset) or NOT_RECORDED),
            _row("strain_resolution_px", "spatial resolution, strain (VSG)", vsg, text=length(vsg) or NOT_RECORDED)]
    unmeasured = "not measured: no static frames (livedic run --static-frames N)"
    for quantity in ("u", "v"):
        item = _floor_item(noise_floor, quantity, "px")
        text = _sd_text(item, 4, "px")
        in_mm = _sd_text(_floor_item(noise_floor, quantity, "mm"), 5, "mm")
        rows.append(_row(f"noise_{quantity}_px", f"noise floor, {quantity} (spatial SD)",
                         None if item is None else item["spatial_sd"],
                         text=(text + (f" = {in_mm}" if in_mm else "")) if text else unmeasured))
    for quantity in ("U", "V", "W"):             # a stereo session's, in space (W along the specimen's normal)
        item = _floor_item(noise_floor, quantity, "mm")
        if item is not None:
            rows.append(_row(f"noise_{quantity}_mm", f"noise floor, {quantity} in space (spatial SD)", item["spatial_sd"],
                             text=_sd_text(item, 5, "mm")))
    for quantity in ("exx", "eyy", "exy"):
        item = _floor_item(noise_floor, quantity, "microstrain")
        rows.append(_row(f"noise_{quantity}_microstrain", f"noise floor, {quantity} (spatial SD)",
                         None if item is None else item["spatial_sd"],
                         text=_sd_text(item, 1, "microstrain") or unmeasured))
    axial = _floor_item(noise_floor, "axial", "microstrain")
    rows.append(_row("noise_axial_microstrain", "noise floor, axial extensometer (temporal SD)",
                     None if axial is None else axial["temporal_sd_mean"],
                     text=_sd_text(axial, 1, "microstrain", "temporal_sd_mean") or unmeasured))
    if verification and verification.get("verified"):
        klass = verification.get("class")
        zero = verification.get("zero_point_class")
        met = (f"class {klass}" if klass else
               f"no class: zero point only, meets class {zero}'s absolute limits" if zero else "no class met")
        text = met + f" (ISO 9513, verified {str(verification.get('date'))[:10]})"
    elif verification and verification.get("in_space"):
        klass, text = None, "not verified: an extensometer in space (stereo) has no verification in livedic yet"
    else:
        klass, text = None, ("not verified (livedic verify or livedic bench extensometer -o FILE.json, then "
                             "--verification FILE.json)")
    rows.append(_row("extensometer_class", "axial extensometer's class", klass, text=text))
    return rows
