"""``livedic report``: the tensile test's result from a recording and the machine's force file.

``livedic report FILE.mcap -o DIR --load csv:FILE (--area MM2 | --width MM --thickness MM)
[--load-offset S]`` writes into DIR (created if missing). Without ``--load``, a recording that
holds the machine's force on ``/machine/force`` gives the force (one value per frame, as
recorded), its cross-section from ``--area`` / ``--width --thickness`` or the session's
``area_mm2``:

``report.json``
    ``E_GPa``, ``Rp02_MPa``, ``Rm_MPa``, ``Ag_percent``, ``A_percent``, ``ReH_MPa``, ``ReL_MPa``,
    ``Ae_percent`` (upper and lower yield strength, yield point extension: null with a reason on
    continuous yielding); ``curve_shape`` ``{"value": "continuous" | "plateau" | "upper_yield_point"
    | "undetermined", "label": text}``; ``Ag_rule`` ``{"value": "at_maximum" | "plateau_middle", "label": text,
    "plateau_strain": [start, end] or null, "Ag_percent", "Agt_percent": number or null}`` (where Ag and Agt were read:
    the frame of Rm, or the middle of a plateau at maximum force, ``dic.tensile.flat_top``); each property
    ``{"value": number or null, "method": text, "reason": text or null}`` (``reason`` says why a
    value is null); ``poisson_ratio`` (fitted over the elastic range, ``dic.tensile.poisson``) and
    ``plastic_contraction_ratio`` (the same slope over the plastic range, never called Poisson's
    ratio; in this file only), each ``{"value", "stderr", "label", "n_frames", "frames",
    "axial_strain_range", "axial_noise", "basis", "method", "reason"}`` (null with a reason without
    the ``transverse`` extensometer); then ``specimen`` (cross-section, gauge length), ``source``
    (recording, load file, frames, strain settings) and ``noise_floor`` (the static frames' table,
    ``stream.stages.noise_floor.recorded_noise_floor``; null without static frames). Strict JSON: no NaN.
``report.md``
    The same for people: specimen, gauge length, the properties with the method of each, Poisson's
    ratio labelled with its frames and axial strain range, and the stress-strain plot.
``stress_strain.png``
    Engineering curve, true curve up to uniform elongation, Rp0.2, Rm, ReH, ReL and Ae marked.

The strain is the ``axial`` extensometer recomputed from the recorded displacements
(``stream.export.recomputed_strain.axial_series``, as ``livedic export`` does; a stereo recording's is its
extensometer in space as recorded, L / L0 - 1 in mm, with a ``stereo`` section: the rig, L0 in space), the stress ``F / A0``
(``stream.stages.stress``); the properties are ``dic.tensile.properties.tensile_properties`` of that
engineering curve (ISO 6892-1: E by a least-squares line over a stated stress range, Rp0.2 by the
0.2 % offset line, Rm at maximum force, Ag, A at the force drop). Files are written atomically and
only all together; existing ones are kept unless ``--overwrite``.
"""

from __future__ import annotations

import io
import math
import os
from datetime import datetime, timezone
from typing import TYPE_CHECKING, Any, Mapping, Sequence

import numpy as np

from livedic.acquire.atomic_file import atomic_files
from livedic.stream.export.report_html import report_html
from livedic.stream.export.report_tables import (Row, analysis_rows, hardware_rows, performance_rows, rows_json,
                                                 rows_markdown)
from livedic.stream.export.report_verification import (VERIFICATION_KEY, axial_end_fit, verification_markdown,
                                                       verification_section)
from livedic.stream.output.files import check_output_folder, json_text

if TYPE_CHECKING:
    from livedic.dic.tensile.poisson import ContractionRatio
    from livedic.dic.tensile.properties import TensileProperties, UniformElongation
    from livedic.stream.stages.stress import StressOptions

__all__ = ["REPORT_FILES", "PROPERTY_KEYS", "YIELD_KEYS", "CURVE_SHAPE_KEY", "AG_RULE_KEY", "report_recording",
           "report_json",
           "report_markdown"]

REPORT_FILES = ("report.md", "report.json", "report.html", "stress_strain.png")
PROPERTY_KEYS = ("E_GPa", "Rp02_MPa", "Rm_MPa", "Ag_percent", "A_percent", "ReH_MPa", "ReL_MPa", "Ae_percent")
YIELD_KEYS = ("ReH_MPa", "ReL_MPa", "Ae_percent")      # null on continuous yielding: no yield phenomenon
CURVE_SHAPE_KEY = "curve_shape"
STEREO_SECTION_KEY = "stereo"   # a stereo recording's rig and strain in space (null for one camera)
STEREO_STRAIN = ("the axial extensometer in space, L / L0 - 1, L the distance in space between its ends, each "
                 "fitted in X, Y, Z over its band of triangulated points (dic.stereo.extensometer)")
AG_RULE_KEY = "Ag_rule"          # where Ag and Agt were read: at maximum force, or the middle of a plateau there
POISSON_KEY = "poisson_ratio"
CONTRACTION_KEYS = (POISSON_KEY, "plastic_contraction_ratio")   # report.json only: the plastic one is no property
PROPERTY_TITLES = {"E_GPa": ("E", "GPa"), "Rp02_MPa": ("Rp0.2", "MPa"), "Rm_MPa": ("Rm", "MPa"),
                   "Ag_percent": ("Ag", "%"), "A_percent": ("A", "%"), "ReH_MPa": ("ReH", "MPa"),
                   "ReL_MPa": ("ReL", "MPa"), "Ae_percent": ("Ae", "%")}


def report_json(properties: TensileProperties, specimen: dict[str, Any], source: dict[str, Any],
                contraction: Sequence[ContractionRatio] | None = None, *,
                tables: Sequence[tuple[str, str, Sequence[Row]]] = ()) -> dict[str, Any]:
    """The ``report.json`` object: the five properties (NaN as null), Poisson's ratio and the plastic contraction
    ratio (``contraction``: the pair of ``dic.tensile.poisson.ContractionRatio``; NaN with NO_PAIR when None),
    ``specimen``, ``source`` and each of ``tables`` (key, heading, rows: ``stream.export.report_tables``) as
    key -> {parameter: value}."""
    from livedic.dic.tensile.poisson import without_pair
    out = {}
    for key, item in properties.as_dict().items():
        value = item["value"]
        out[key] = {"value": value if math.isfinite(value) else None, "method": item["method"],
                    "reason": item["reason"]}
    out[CURVE_SHAPE_KEY] = {"value": properties.curve_shape.name.lower(), "label": properties.curve_shape.value}
    out[AG_RULE_KEY] = _ag_rule(properties.Ag_percent)
    for key, ratio in zip(CONTRACTION_KEYS, contraction or without_pair()):
        out[key] = {name: _finite_or_none(value) for name, value in ratio.as_dict().items()}
    out["specimen"] = specimen
    out["source"] = source
    for key, _heading, rows in tables:
        out[key] = _finite_or_none_dict(rows_json(rows))
    return out


def _ag_rule(ag: UniformElongation) -> dict[str, Any]:
    """``{"value": "at_maximum" | "plateau_middle", "label": text, "plateau_strain": [start, end] or null,
    "Agt_percent": number or null}``: where Ag and Agt were read, the plateau's strains when one was found."""
    from livedic.dic.tensile.flat_top import AgRule
    top = ag.top
    plateau = list(top.strains) if top is not None and top.rule is AgRule.PLATEAU_MIDDLE else None
    return {"value": ag.rule.name.lower(), "label": ag.rule.value, "plateau_strain": plateau,
            "Ag_percent": _finite_or_none(float(ag.value)), "Agt_percent": _finite_or_none(float(ag.total))}


def _finite_or_none_dict(values: Mapping[str, Any]) -> dict[str, Any]:
    return {key: _finite_or_none(value) for key, value in values.items()}


def _finite_or_none(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, list):
        return [_finite_or_none(v) for v in value]
    return value


def report_markdown(report: Mapping[str, Any], plot_name: str, title: str, *,
                    tables: Sequence[tuple[str, str, Sequence[Row]]] = ()) -> str:
    """``report.md`` text from the ``report_json`` object, with ``tables`` (key, heading, rows) after the
    specimen."""
    specimen, source = report["specimen"], report["source"]
    gauge = f"{specimen['gauge_length_px']:.1f} px"
    if specimen.get("gauge_length_in_space"):
        gauge = (f"{specimen['gauge_length_mm']:.3f} mm measured in space (stereo; its ends {gauge} apart in the "
                 f"left view)")
    elif specimen.get("gauge_length_mm") is not None:
        origin = f", {specimen['scale_origin']}" if specimen.get("scale_origin") else ""
        gauge += f" = {specimen['gauge_length_mm']:.3f} mm ({specimen['scale_px_per_mm']:g} px/mm{origin})"
    lines = [f"# Tensile test: {title}", "",
             "## Specimen", "",
             f"- cross-section A0: {specimen['area_mm2']:g} mm^2",
             f"- gauge length L0 (virtual extensometer `axial`): {gauge}", ""]
    lines += _stereo_markdown(report.get(STEREO_SECTION_KEY))
    for _key, heading, rows in tables:
        lines += rows_markdown(rows, heading)
    lines += verification_markdown(report.get(VERIFICATION_KEY))
    lines += ["## Properties (ISO 6892-1)", "",
              f"Curve shape: {report[CURVE_SHAPE_KEY]['label']}.", "",
              *_ag_rule_markdown(report.get(AG_RULE_KEY)),
             "| property | value | unit | method | why missing |",
             "|---|---|---|---|---|"]
    for key in PROPERTY_KEYS:
        name, unit = PROPERTY_TITLES[key]
        item = report[key]
        value = "n/a" if item["value"] is None else f"{item['value']:.4g}"
        lines.append(f"| {name} | {value} | {unit} | {_cell(item['method'])} | {_cell(item['reason'] or '')} |")
    nu = report[POISSON_KEY]
    value = "n/a" if nu["value"] is None else f"{nu['value']:.3f} +- {nu['stderr']:.3f}"
    lines.append(f"| {nu['label']} | {value} | - | {_cell(nu['method'])} (ASTM E132) | {_cell(nu['reason'] or '')} |")
    lines += noise_floor_markdown(report.get("noise_floor"))
    lines += ["", "## Stress-strain curve", "", f"![stress-strain curve]({plot_name})", "",
              "Engineering stress F / A0 against the axial extensometer's engineering strain; true stress and "
              "strain only up to uniform elongation (maximum force), where the uniform-deformation formulas "
              "stop holding.", "",
              "## Source", "",
              f"- recording: `{source['recording']}`" + (" (truncated: what could be recovered)"
                                                        if source["truncated"] else ""),
              _force_line(source),
              f"- {source['strain']}",
              f"- written {source['generated_at']} by livedic report", ""]
    return "\n".join(lines)


def stereo_section(session: Mapping[str, Any], l0_mm: float) -> dict[str, Any] | None:
    """``report.json``'s ``stereo``: the rig and how the strain was measured in space (None for one camera)."""
    from livedic.stream.export.recomputed_strain import recorded_rig
    rig = recorded_rig(session)
    if rig is None:
        return None
    return {"baseline_mm": rig.baseline_mm, "angle_deg": rig.angle_deg, "calibration_rms_px": rig.rms_px,
            "calibration_pairs": len(rig.pairs), "calibration_from": session["stereo"].get("calibration_from"),
            "axial_L0_mm": l0_mm, "strain": STEREO_STRAIN}


def _stereo_markdown(stereo: Mapping[str, Any] | None) -> list[str]:
    """The report's stereo section (none for one camera)."""
    if stereo is None:
        return []
    fit = (f", reprojection RMS {stereo['calibration_rms_px']:.3f} px over {stereo['calibration_pairs']} target pairs"
           if stereo["calibration_pairs"] else "")
    l0 = "not measured" if stereo["axial_L0_mm"] is None else f"{stereo['axial_L0_mm']:.3f} mm"
    return ["## Stereo measurement", "",
            f"- two calibrated cameras: baseline {stereo['baseline_mm']:.1f} mm, {stereo['angle_deg']:.1f} degrees "
            f"apart; calibration: {stereo['calibration_from']}{fit}",
            f"- strain: {stereo['strain']}; L0 {l0} measured in space",
            "- out-of-plane motion of the specimen (towards or away from the cameras, a turn) is not read as strain, "
            "as a single camera reads it", ""]


def _ag_rule_markdown(rule: Mapping[str, Any] | None) -> list[str]:
    """The line saying where Ag and Agt were read (none for a report.json written before the rule)."""
    if rule is None:
        return []
    if rule.get("Ag_percent", 0.0) is None and rule["Agt_percent"] is None:
        return ["Ag and Agt not read: the maximum force is undefined (Rm n/a, its reason in the table).", ""]
    agt = "n/a" if rule["Agt_percent"] is None else f"{rule['Agt_percent']:.4g} %"
    line = f"Ag and Agt read {rule['label']}; Agt {agt}"
    if rule["plateau_strain"] is not None:
        start, end = rule["plateau_strain"]
        line += f"; plateau from {100 * start:.3f} % to {100 * end:.3f} % strain"
    return [line + ".", ""]


def guide_tables(session: Mapping[str, Any], *, scale: tuple[float | None, str | None],
                 noise_floor: Mapping[str, Any] | None, verification: Mapping[str, Any]
                 ) -> list[tuple[str, str, Sequence[Row]]]:
    """The iDICs guide's tables of a session (key, heading, rows): hardware, analysis, measured performance."""
    return [("hardware", "Hardware (iDICs guide)", hardware_rows(session, scale=scale,
                                                                 calibration=session.get("calibration"))),
            ("analysis", "Analysis (iDICs guide)", analysis_rows(session)),
            ("performance", "Measured performance (iDICs guide)",
             performance_rows(session, noise_floor=noise_floor, verification=verification, scale=scale[0]))]


def specimen_scale(given: float | None, session: Mapping[str, Any]) -> tuple[float | None, str | None]:
    """(px/mm, where it comes from) for the specimen's lengths: the session's scale, else the simulator's own
    (its images are rendered at a known scale), else (None, None)."""
    calibration = session.get("calibration") or {}
    if given and session.get("scale_px_per_mm") is None and calibration.get("px_per_mm"):
        return float(given), "the calibration's target on the specimen plane"
    if given:
        return float(given), "the session's --scale"
    settings = session.get("source_settings") or {}
    if str(settings.get("uri", "")).startswith("synthetic:") and settings.get("scale"):
        return float(settings["scale"]), "the simulator's rendering scale"
    return None, None


def noise_floor_markdown(floor: Mapping[str, Any] | None) -> list[str]:
    """The report's noise-floor section (``stream.stages.noise_floor``): the table, or why there is none."""
    from livedic.stream.stages.noise_floor import NOISE_FLOOR_COLUMNS, noise_floor_rows
    lines = ["", "## Noise floor", ""]
    if floor is None:
        return lines + ["No static frames were recorded (`livedic run --static-frames N` takes them): the "
                        "measurement's noise floor is unknown."]
    lines += [f"On the {len(floor['frames_used'])} static frames after the reference (frames "
              f"{', '.join(map(str, floor['frames_used']))}), strain as recorded: the spatial SD over the points of "
              f"a frame (mean over the frames), the temporal SD of each point over the frames (mean and max over the "
              f"points), and the mean (bias), as the iDICs Good Practices Guide defines them.", "",
              "| " + " | ".join(NOISE_FLOOR_COLUMNS) + " |", "|" + "---|" * len(NOISE_FLOOR_COLUMNS)]
    lines += ["| " + " | ".join(_cell(cell) for cell in row) + " |" for row in noise_floor_rows(floor)]
    return lines


def _force_line(source) -> str:
    """The report's line on where the force came from: the load and its offset, or the recorded channel."""
    counted = f"force at {source['frames_with_force']} of {source['frames']} frames"
    if "recorded_source" in source:
        origin = f" (from `{source['recorded_source']}`)" if source["recorded_source"] else ""
        return f"- force: as recorded on `/machine/force`{origin}; {counted}"
    return f"- force: `{source['load']}`, offset {source['load_offset_s']:g} s; {counted}"


def _cell(text):
    return str(text).replace("|", "\\|").replace("\n", " ")


def report_recording(path: str | os.PathLike[str], directory: str | os.PathLike[str], *, stress: StressOptions,
                     strain: Mapping[str, Any] | None = None, overwrite: bool = False,
                     verification: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Write ``REPORT_FILES`` for recording ``path`` into ``directory``; returns the ``report.json`` object.

    Parameters
    ----------
    path, directory : str or os.PathLike
    stress : stream.stages.stress.StressOptions
        Force file, its offset, and A0; ``load`` ``RECORDED_FORCE`` for the recording's own force.
    strain : dict, optional
        Strain settings replacing the recorded ones (``stream.stages.strain.overrides_from_args``).
    overwrite : bool
    verification : dict, optional
        ``livedic verify -o`` or ``livedic bench extensometer -o`` (``report_verification.load_verification``): the class it states.

    Raises
    ------
    ValueError
        ``directory`` is a file or holds the files without ``overwrite``, the recording or the load
        file cannot be used, or there is no ``axial`` extensometer: one line, nothing written.
    """
    from livedic.acquire.force import open_load
    from livedic.acquire.recording.reader import Recording
    from livedic.dic.tensile.poisson import contraction_ratios
    from livedic.dic.tensile.properties import tensile_properties
    from livedic.stream.export.force import RecordedForce
    from livedic.stream.export.notes import reader_notes
    from livedic.stream.export.recomputed_strain import axial_series
    from livedic.stream.stages.noise_floor import recorded_noise_floor
    from livedic.stream.stages.stress import plot_stress_strain, stress_strain_table

    path, directory = os.fspath(path), os.fspath(directory)
    check_output_folder(directory, "-o")
    targets = {name: os.path.join(directory, name) for name in REPORT_FILES}
    existing = [name for name, target in targets.items() if os.path.lexists(target)]
    if existing and not overwrite:
        raise ValueError(f"{directory} already holds {', '.join(existing)}: pass --overwrite to replace "
                         f"{'it' if len(existing) == 1 else 'them'}, or choose another folder")
    series = axial_series(path, strain)                   # every check before DIR is made
    if stress.recorded:
        with reader_notes():                              # axial_series has reported them
            recorded = RecordedForce.read(Recording(path))
        force = recorded.on_frames(series["frames"])
    else:
        force = open_load(stress.load, offset_s=stress.offset_s).force_at(series["time_s"])
    table = stress_strain_table(series["frames"], series["time_s"], force, series["eng_strain"], stress.area_mm2)
    properties = tensile_properties(table.eng_strain, table.eng_stress_MPa)
    with reader_notes():
        noise_floor = recorded_noise_floor(Recording(path))
    test = ~np.isin(table.frame, noise_floor["frames_used"] if noise_floor else [])   # static frames: no test
    contraction = (contraction_ratios(series["eng_strain"][test], series["transverse_eng_strain"][test],
                                      force=table.force_N[test], frames=table.frame[test])
                   if series["has_transverse"] else None)
    specimen, scale, scale_origin = _specimen_section(series, stress.area_mm2)
    source = _source_section(path, series, stress, table, recorded.source if stress.recorded else None)
    session = series["metadata"]
    verified = verification_section(verification, gauge_length_px=series["l0_px"], subset=session.get("subset"),
                                    scale_px_per_mm=scale, end_fit=axial_end_fit(session),
                                    in_space=bool(series["stereo"]))
    tables = guide_tables(session, scale=(scale, scale_origin), noise_floor=noise_floor, verification=verified)
    report = report_json(properties, specimen, source, contraction, tables=tables)
    report[VERIFICATION_KEY] = verified
    report[STEREO_SECTION_KEY] = stereo_section(session, specimen["gauge_length_mm"])
    report["noise_floor"] = noise_floor
    title = os.path.basename(path)
    plot = io.BytesIO()
    in_space = ", strain in space: stereo" if series["stereo"] else ""
    plot_stress_strain(plot, table, properties=properties,
                       title=f"{title}: stress-strain (A0 {stress.area_mm2:g} mm^2{in_space})")
    _write_report_files(targets, report, report_markdown(report, "stress_strain.png", title, tables=tables),
                        plot.getvalue(), title)
    return report


def _specimen_section(series: Mapping[str, Any], area_mm2: float) -> tuple[dict[str, Any], float | None, str | None]:
    """``report.json``'s specimen (A0, L0 in px and mm) and the scale the report uses, with its origin; a stereo
    recording's L0 is the one measured in space, with no scale involved."""
    scale, scale_origin = specimen_scale(series["scale"], series["metadata"])
    specimen = {"area_mm2": area_mm2, "gauge_length_px": series["l0_px"],
                "gauge_length_mm": series["l0_px"] / scale if scale else None, "scale_px_per_mm": scale,
                "scale_origin": scale_origin, "gauge_length_in_space": series["stereo"]}
    if series["stereo"]:
        l0_mm = series["l0_mm_in_space"]
        scale, scale_origin = None, None
        specimen.update(gauge_length_mm=l0_mm if math.isfinite(l0_mm) else None, scale_px_per_mm=None,
                        scale_origin=None)
    return specimen, scale, scale_origin


def _source_section(path: str, series: Mapping[str, Any], stress: StressOptions, table: Any,
                    recorded_source: str | None) -> dict[str, Any]:
    """``report.json``'s ``source``: the recording, the force and how much of the test it covers, the strain."""
    from livedic.stream.stages.stress import force_coverage_notes
    return {"recording": os.path.abspath(path), "truncated": bool(series["truncated"]), "load": stress.load,
            "load_offset_s": stress.offset_s, "frames": int(table.frame.size),
            "frames_with_force": int(sum(math.isfinite(f) for f in table.force_N)),
            "uniform_frame": int(table.frame[table.uniform_frame]) if table.uniform_frame >= 0 else None,
            "strain": series["strain"],
            "notes": series["notes"] + force_coverage_notes(table.frame, table.time_s, table.force_N,
                                                            table.eng_strain),
            **({"recorded_source": recorded_source} if stress.recorded else {}),
            "generated_at": datetime.now(timezone.utc).isoformat()}


def _write_report_files(targets: Mapping[str, str], report: Mapping[str, Any], text: str, plot_png: bytes,
                        title: str) -> None:
    """``REPORT_FILES`` written together, atomically: all of them or none."""
    with atomic_files(targets, binary={name for name in targets if name.endswith(".png")}) as staged:
        staged["report.json"].write(json_text(report))
        staged["report.md"].write(text)
        staged["report.html"].write(report_html(text, {"stress_strain.png": plot_png}, title))
        staged["stress_strain.png"].write(plot_png)
