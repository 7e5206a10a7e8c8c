"""The report's "extensometer verification (ISO 9513)" section, from ``livedic bench extensometer -o FILE.json``.

``livedic report --verification FILE.json`` states the class the session's axial extensometer was verified to,
with the table it was verified by (per step: true elongation, mean reading, bias, resolution, class), the date
and the settings; a warning line when the session's gauge length, subset, scale or axial end fit
(``--extensometer-ends``) differs from the verification's (the class is of the verified extensometer, not necessarily of this one). Without the file the
section says the class was not verified and names the command. ``report.json`` holds the same under
``extensometer_verification``.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from typing import Any

from livedic.dic.strain.extensometer import AXIAL, LOCAL

__all__ = ["load_verification", "verification_section", "verification_markdown", "classified_entry",
           "verification_table_lines", "write_verification", "axial_end_fit"]

VERIFICATION_KEY = "extensometer_verification"
VERIFICATION_KIND = "livedic extensometer verification"       # the mark bench.extensometer writes into its -o file
VERIFY_COMMAND = ("livedic verify REFERENCE IMAGES... --gauge-length L0_PX --scale PX_PER_MM -o verification.json (your "
                  "own frames) or livedic bench extensometer --gauge-length L0_PX --scale PX_PER_MM -o "
                  "verification.json (rendered frames)")
USER_FRAMES = "user frames"      # settings["source"] of a verification on a user's own images (livedic verify)
LENGTH_TOLERANCE_PX = 0.5        # gauge lengths closer than this are the same extensometer


def load_verification(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a ``livedic bench extensometer -o`` or ``livedic verify -o`` file.

    Raises
    ------
    ValueError
        Not a file, not JSON, or not a verification: one line saying what to give.
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise ValueError(f"--verification {path} is not a file: give the JSON written by {VERIFY_COMMAND}")
    try:
        with open(path, encoding="utf-8") as handle:
            data = json.load(handle)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"--verification {path} cannot be read as JSON ({error}): give the file written by "
                         f"livedic verify -o or livedic bench extensometer -o") from None
    if (not isinstance(data, dict) or data.get("kind") != VERIFICATION_KIND
            or not isinstance(data.get("gauge_lengths"), list) or not data["gauge_lengths"]):
        raise ValueError(f"--verification {path} is not an extensometer verification: give the file written by "
                         f"livedic verify -o or livedic bench extensometer -o")
    return data


def axial_end_fit(session: Mapping[str, Any]) -> str:
    """The axial extensometer's end fit recorded in a session's metadata (local before the choice existed)."""
    return str((session.get("extensometer_end_fits") or {}).get(AXIAL, LOCAL))


def verification_section(verification: Mapping[str, Any] | None, *, gauge_length_px: float,
                         subset: int | None, scale_px_per_mm: float | None,
                         end_fit: str | None = None, in_space: bool = False) -> dict[str, Any]:
    """The ``report.json`` section: the class of the verified gauge length nearest the session's, its table,
    date, settings and warnings; or ``{"verified": False, ...}`` naming the command. ``end_fit``: the session's
    axial end fit (a verification written before the choice existed was made with local ends). ``in_space``: a
    stereo session's extensometer, which ``livedic verify`` (one camera) does not verify: never a class."""
    if in_space:
        given = (" (the verification file given is of a one-camera extensometer and does not apply)"
                 if verification is not None else "")
        return {"verified": False, "class": None, "in_space": True,
                "statement": f"the extensometer in space (stereo) has no ISO 9513 verification in livedic yet: "
                             f"livedic verify and livedic bench extensometer verify a one-camera extensometer{given}"}
    if verification is None:
        return {"verified": False, "class": None,
                "statement": f"the extensometer's ISO 9513 class was not verified: run {VERIFY_COMMAND} and pass "
                             f"--verification verification.json to livedic report"}
    entries = verification["gauge_lengths"]
    entry = min(entries, key=lambda e: abs(float(e["l0_px"]) - gauge_length_px))
    settings = verification.get("settings", {})
    warnings = []
    if not abs(float(entry["l0_px"]) - gauge_length_px) <= LENGTH_TOLERANCE_PX:
        verified = ", ".join(f"{float(e['l0_px']):g}" for e in entries)
        warnings.append(f"the session's gauge length {gauge_length_px:g} px differs from every verified one "
                        f"({verified} px): the class stated is of {float(entry['l0_px']):g} px")
    if subset is not None and settings.get("subset") is not None and int(settings["subset"]) != int(subset):
        warnings.append(f"the session's subset {subset} px differs from the verification's {settings['subset']} px")
    verified_fit = settings.get("end_fit") or LOCAL
    if end_fit is not None and verified_fit != end_fit:
        warnings.append(f"the session's extensometer ends are {end_fit}, the verification's {verified_fit}: "
                        f"their noise differs (--extensometer-ends)")
    verified_scale = settings.get("scale_px_per_mm")
    if verified_scale is None:
        warnings.append("verified without a scale: relative limits only, zero-elongation steps not classified")
    elif scale_px_per_mm is not None and not math.isclose(float(verified_scale), scale_px_per_mm, rel_tol=1e-3):
        warnings.append(f"verified at {float(verified_scale):g} px/mm, the session's scale is "
                        f"{scale_px_per_mm:g} px/mm: the absolute (um) limits differ")
    return {"verified": True, "class": entry["met_class"], "reason": entry.get("reason_text"),
            "l0_px": entry["l0_px"], "l0_mm": entry.get("l0_mm"), "limitations": entry.get("limitations", []),
            "zero_point_class": entry.get("zero_point_class"),
            "steps": entry["steps"], "date": verification.get("date"), "settings": dict(settings),
            "standard": verification.get("standard"), "warnings": warnings}


def verification_markdown(section: Mapping[str, Any] | None) -> list[str]:
    """report.md lines of the section (none for a report made before it existed)."""
    if section is None:
        return []
    lines = ["## Extensometer verification (ISO 9513)", ""]
    if not section["verified"]:
        return lines + [f"- {section['statement']}", ""]
    settings = section["settings"]
    mm = f" = {section['l0_mm']:g} mm" if section.get("l0_mm") is not None else ""
    lines += [f"- class met: **{section['class'] or 'none'}**" + ("" if section["class"] else f" ({section['reason']})")
              + f" at L0 {section['l0_px']:g} px{mm}", f"- verified {section['date']} by {_how_verified(settings)}, "
              f"subset {settings.get('subset')} px, points every {settings.get('step_px')} px, "
              f"{settings.get('end_fit') or LOCAL} ends, scale "
              f"{settings.get('scale_px_per_mm') or 'none'} px/mm; {section.get('standard') or 'ISO 9513:2012 Table 2'}; "
              f"bias = mean reading - true, resolution = half the range of the held readings"]
    if section.get("zero_point_class"):
        lines.append(f"- the zero point (static frames, rigid motions) meets class {section['zero_point_class']}'s "
                     f"absolute limits")
    lines += [f"- limitation: {text}" for text in section["limitations"]]
    lines += [f"- **warning**: {text}" for text in section["warnings"]]
    lines += ["", "| step | true elongation px | mean reading px | bias um | relative bias % | resolution um | class |",
              "|---|---|---|---|---|---|---|"]
    for row in section["steps"]:
        lines.append(f"| {row.get('label', '')} | {row['true_px']:.4f} | {_number(row['mean_px'], '.4f')} | "
                     f"{_number(row['bias_um'], '.2f')} | {_number(_percent(row['relative_bias']), '.3f')} | "
                     f"{_number(row['resolution_um'], '.2f')} | {row['best_class'] or '-'} |")
    return lines + [""]


def _how_verified(settings: Mapping[str, Any]) -> str:
    """Who made the verification's frames: the user's own images (``livedic verify``) or the bench's renders."""
    if settings.get("source") == USER_FRAMES:
        known = (f"known elongations from {settings['elongations_file']}" if settings.get("elongations_file")
                 else "all of known zero elongation (static frames, rigid motions)")
        return (f"`livedic verify` on the user's own images ({len(settings.get('images') or [])} against the "
                f"reference {settings.get('reference')}; {known})")
    return (f"`livedic bench extensometer`: exact rendered known elongations (rigid translations, uniform stretches), "
            f"{settings.get('frames_per_step')} frames per step, noise {settings.get('noise')} grey levels "
            f"({settings.get('bit_depth')}-bit)")


def _percent(fraction: float | None) -> float | None:
    return None if fraction is None else 100.0 * fraction


def _number(value: Any, spec: str) -> str:
    return "n/a" if value is None else format(value, spec)


def classified_entry(true_px: Sequence[float], readings_px: Sequence[Any], l0_px: float,
                     scale_px_per_mm: float | None, *, labels: Sequence[str]) -> dict[str, Any]:
    """One gauge length's ISO 9513 verdict (``dic.strain.iso9513.classify``, JSON-ready) as a verification file
    holds it: each step with its ``label``, ``strain`` (true / L0) and ``readings_px``, and the ``limiting``
    step's index and reason."""
    from livedic.dic.strain.iso9513 import classify, limiting_step
    result = classify(true_px, readings_px, l0_px, scale_px_per_mm=scale_px_per_mm)
    entry = result.as_dict()
    for row, label, true, held_px in zip(entry["steps"], labels, true_px, readings_px):
        row.update(label=label, strain=float(true) / l0_px, readings_px=[float(v) for v in held_px])
    limit = limiting_step(result)
    entry["limiting_step"] = None if limit is None else {"index": limit[0], "label": labels[limit[0]],
                                                         "reason": limit[1]}
    return entry


def write_verification(path: str | os.PathLike[str], result: Mapping[str, Any]) -> None:
    """Write ``result`` (``settings``, ``gauge_lengths``, ...) as strict JSON, atomically, marked as a
    verification: what ``livedic report --verification`` reads."""
    from livedic.stream.output.files import json_text, write_text_atomic
    write_text_atomic(path, json_text({"kind": VERIFICATION_KIND, **result}))


def verification_table_lines(entry: Mapping[str, Any]) -> list[str]:
    """One gauge length's table as printed: per step the known elongation, mean reading, bias, resolution (px,
    um, %) and class; the class met with the limiting step's reason, the limitations, the zero point."""
    mm = f" = {entry['l0_mm']:g} mm" if entry["l0_mm"] is not None else ""
    limit = entry.get("limiting_step")
    lines = ["", f"L0 {entry['l0_px']:g} px{mm}: class {entry['met_class'] or 'none'}"
             + ("" if entry["met_class"] else f" ({entry['reason_text']})")]
    if limit:
        lines.append(f"  limiting step {limit['label']}: {limit['reason']}")
    lines += [f"  limitation: {text}" for text in entry["limitations"]]
    if entry.get("zero_point_class") and not entry.get("elongation_verified", True):
        lines.append(f"  zero point only: it meets class {entry['zero_point_class']}'s absolute limits; "
                     f"a known non-zero elongation (--elongations) is needed to verify a class")
    lines.append(f"  {'step':>18s} {'true px':>9s} {'mean px':>10s} {'bias px':>9s} {'bias um':>8s} "
                 f"{'rel bias %':>10s} {'res px':>8s} {'res um':>7s} {'rel res %':>9s} {'class':>5s}")
    for row in entry["steps"]:
        rel_bias = None if row["relative_bias"] is None else 100 * row["relative_bias"]
        rel_res = (None if row["relative_resolution"] is None or row["true_px"] == 0
                   else 100 * row["relative_resolution"])
        lines.append(f"  {row['label']:>18s} {row['true_px']:9.4f} {_width(row['mean_px'], '10.4f')} "
                     f"{_width(row['bias_px'], '9.4f')} {_width(row['bias_um'], '8.2f')} {_width(rel_bias, '10.3f')} "
                     f"{_width(row['resolution_px'], '8.4f')} {_width(row['resolution_um'], '7.2f')} "
                     f"{_width(rel_res, '9.3f')} {row['best_class'] or '-':>5s}")
    return lines


def _width(value: Any, spec: str) -> str:
    return "n/a".rjust(int(spec.split(".")[0])) if value is None else format(value, spec)
