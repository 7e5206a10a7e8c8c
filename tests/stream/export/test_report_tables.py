"""Tests of stream/export/report_tables.py: the hardware and analysis tables from a session's metadata."""

from livedic.dic.subpixel.method import METHODS
from livedic.stream.export.report_tables import (NOT_RECORDED, analysis_rows, camera_description, hardware_rows,
                                                 rows_json, rows_markdown)

ARAVIS = {"source": "aravis", "uri": "aravis:Cam1", "vendor": "Basler", "model": "acA2440-75um", "serial": "40123",
          "sensor_size": [2448, 2048], "width": 2048, "height": 1536, "bit_depth": 12, "frame_rate": 75.0,
          "exposure_us": 2000.0}


def test_a_camera_is_named_with_its_vendor_model_serial_and_settings():
    assert camera_description(ARAVIS) == ("Basler acA2440-75um", "40123")
    table = rows_json(hardware_rows({"source_settings": ARAVIS, "frame_size": [2048, 1536], "scale_px_per_mm": 12.5}))
    assert table["sensor_size_px"] == [2448, 2048] and table["image_size_px"] == [2048, 1536]
    assert table["bit_depth"] == 12 and table["frame_rate_fps"] == 75.0 and table["exposure_us"] == 2000.0
    assert table["scale_px_per_mm"] == 12.5 and table["calibration"] is None


def test_what_was_not_recorded_says_so_and_is_null_never_a_guess():
    rows = hardware_rows({"source_settings": {"uri": "images:/data/*.tif"}})
    by_key = {row.key: row for row in rows}
    assert by_key["camera"].value == "images from images:/data/*.tif"
    for key in ("sensor_size_px", "image_size_px", "bit_depth", "frame_rate_fps", "exposure_us"):
        assert by_key[key].value is None and by_key[key].text == NOT_RECORDED, key
    assert by_key["scale_px_per_mm"].text.startswith("none")


def test_the_analysis_table_describes_the_method_that_ran():
    session = {"software_version": "0.1.0", "subset": 31, "grid_step": 9, "subpixel": "icgn2",
               "search": "improved-wso", "strain_window": 7, "vsg_px": 85.0, "strain_measure": "green",
               "reference_update": "auto"}
    table = rows_json(analysis_rows(session))
    assert table["software"] == "livedic 0.1.0" and table["subset_px"] == 31 and table["step_px"] == 9
    assert table["shape_function"] == METHODS["icgn2"].shape_function and "second order" in table["shape_function"]
    assert table["interpolant"] == METHODS["icgn2"].interpolant and "B-spline" in table["interpolant"]
    assert table["vsg_px"] == 85.0 and table["strain_measure"] == "green" and table["prefilter"] == "none"
    # the interpolant of the recorded --interpolation; recordings without it sampled the cubic
    quintic = rows_json(analysis_rows(dict(session, subpixel="icgn", interpolation="bspline5")))
    assert "biquintic B-spline" in quintic["interpolant"]
    assert "bicubic B-spline" in rows_json(analysis_rows(dict(session, subpixel="icgn")))["interpolant"]
    assert "bspline9" in rows_json(analysis_rows(dict(session, subpixel="icgn", interpolation="bspline9")))["interpolant"]
    surface = rows_json(analysis_rows(dict(session, subpixel="improved-surface-fit")))
    assert surface["interpolant"] == METHODS["improved-surface-fit"].interpolant
    # an unknown method is not described by another's traits
    assert rows_json(analysis_rows({"subpixel": "mystery"}))["shape_function"] is None


def test_every_method_declares_its_shape_function_interpolant_and_criterion():
    for method in METHODS.values():
        assert method.shape_function and method.interpolant and method.criterion, method.name
        assert ("first order" in method.shape_function) == (method.shape_order == 1), method.name


def test_markdown_table_escapes_cells():
    lines = rows_markdown(hardware_rows({"source_settings": {"uri": "a|b"}}), "Hardware")
    assert lines[0] == "## Hardware" and lines[2] == "| parameter | value |"
    assert "images from a\\|b" in "\n".join(lines)


def test_the_scale_row_names_where_the_scale_comes_from():
    from livedic.stream.export.report import specimen_scale
    simulated = {"source_settings": {"uri": "synthetic:tensile?frames=9", "scale": 10.0}}
    assert specimen_scale(None, simulated) == (10.0, "the simulator's rendering scale")
    assert specimen_scale(12.5, simulated) == (12.5, "the session's --scale")
    assert specimen_scale(None, {"source_settings": {"uri": "aravis:Cam1"}}) == (None, None)
    row = {r.key: r for r in hardware_rows(simulated, scale=specimen_scale(None, simulated))}["scale_px_per_mm"]
    assert row.value == 10.0 and row.text == "10 px/mm (the simulator's rendering scale)"


def test_a_recorded_calibration_is_described_and_its_scale_named():
    from livedic.stream.export.report import specimen_scale
    calibration = {"target": "chessboard:9x6", "square_mm": 5.0, "images": [{}] * 8, "rms_px": 0.047,
                   "camera_matrix": [[1023.7, 0, 511.3], [0, 1023.9, 511.6], [0, 0, 1]],
                   "dist_coeffs": [-0.118, -0.0074, 0, 0, 0], "plane": {"tilt_deg": 1.2}, "px_per_mm": 10.0002}
    session = {"source_settings": {"source": "aravis", "vendor": "Basler", "model": "a2A"}, "calibration": calibration,
               "scale_px_per_mm": None}
    scale = specimen_scale(10.0002, session)
    assert scale == (10.0002, "the calibration's target on the specimen plane")
    rows = {r.key: r for r in hardware_rows(session, scale=scale, calibration=calibration)}
    assert rows["calibration"].value is calibration
    text = rows["calibration"].text
    assert "chessboard:9x6" in text and "8 views" in text and "0.047 px" in text and "k1 -0.118" in text
    assert "tilted 1.2 deg" in text and text.endswith("lens distortion removed before strain")


def test_the_performance_table_reads_the_noise_floor_and_the_verified_class():
    from livedic.stream.export.report_tables import performance_rows
    floor = {"table": [
        {"quantity": "u", "unit": "px", "spatial_sd": 0.0063, "temporal_sd_mean": 0.0043, "status": "ok"},
        {"quantity": "u", "unit": "mm", "spatial_sd": 0.00063, "temporal_sd_mean": 0.00043, "status": "ok"},
        {"quantity": "v", "unit": "px", "spatial_sd": None, "temporal_sd_mean": None, "status": "too_few_frames"},
        {"quantity": "eyy", "unit": "microstrain", "spatial_sd": 89.7, "temporal_sd_mean": 60.8, "status": "ok"},
        {"quantity": "axial", "unit": "microstrain", "spatial_sd": None, "temporal_sd_mean": 12.5, "status": "ok"}]}
    rows = {r.key: r for r in performance_rows({"subset": 21, "vsg_px": 77.0}, noise_floor=floor,
                                               verification={"verified": True, "class": "0.5", "date": "2026-12-02T1"},
                                               scale=10.0)}
    assert rows["strain_resolution_px"].value == 77.0 and rows["strain_resolution_px"].text == "77 px = 7.700 mm"
    assert rows["noise_u_px"].value == 0.0063 and rows["noise_u_px"].text == "0.0063 px = 0.00063 mm"
    assert rows["noise_v_px"].value is None and rows["noise_v_px"].text.startswith("not measured")   # not ok: no number
    assert rows["noise_eyy_microstrain"].text == "89.7 microstrain"
    assert rows["noise_axial_microstrain"].value == 12.5
    assert rows["extensometer_class"].value == "0.5" and rows["extensometer_class"].text.startswith("class 0.5")
    unverified = {r.key: r for r in performance_rows({}, noise_floor=None, verification={"verified": False}, scale=None)}
    assert unverified["extensometer_class"].value is None and unverified["noise_u_px"].text.startswith("not measured")
    assert unverified["strain_resolution_px"].value is None
    zero_only = {r.key: r for r in performance_rows({}, noise_floor=None, scale=10.0, verification={
        "verified": True, "class": None, "zero_point_class": "0.5", "date": "2026-12-02T1"})}
    assert zero_only["extensometer_class"].value is None       # static and rigid frames only: no class claimed
    assert zero_only["extensometer_class"].text.startswith("no class: zero point only, meets class 0.5's")
    assert "noise_W_mm" not in rows                         # 2D: no rows in space


def test_a_stereo_sessions_noise_floor_in_space_has_its_rows():
    from livedic.stream.export.report_tables import performance_rows
    floor = {"table": [
        {"quantity": "U", "unit": "mm", "spatial_sd": 0.00017, "temporal_sd_mean": 0.00011, "status": "ok"},
        {"quantity": "W", "unit": "mm", "spatial_sd": 0.00076, "temporal_sd_mean": 0.00049, "status": "ok"},
        {"quantity": "V", "unit": "mm", "spatial_sd": None, "temporal_sd_mean": None, "status": "too_few_frames"}]}
    rows = {r.key: r for r in performance_rows({}, noise_floor=floor, verification=None, scale=None)}
    assert rows["noise_U_mm"].value == 0.00017 and rows["noise_W_mm"].text == "0.00076 mm"
    assert "noise_V_mm" not in rows                         # not measured: no row claiming a number
