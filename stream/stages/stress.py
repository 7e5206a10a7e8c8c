"""Stress from the machine's force and the specimen's cross-section: the stress-strain table.

Engineering stress is force over the original cross-section, ``F / A0`` (N / mm^2 = MPa), at
every frame; the strain is the engineering strain of the ``axial`` virtual extensometer.

True strain ``ln(1 + e)`` and true stress ``F / A0 x (1 + e)`` assume uniform deformation at
constant volume: they hold up to uniform elongation Ag, the frame of maximum force. Past it
the neck concentrates the deformation, the gauge length no longer strains uniformly and the
cross-section in the neck is smaller than ``A0 / (1 + e)``: both formulas would be wrong, so
the table gives NaN there (ISO 6892-1 and ASTM E8 read nothing from them past Ag either).

Live, the frame of maximum force is not known yet: ``UniformElongationWatch`` gives true values
while the force stays within ``NECKING_DROP`` (0.5 %) of its running maximum and ends them for good
at the first frame below it (a provisional rule: it may show a few frames past the maximum that
the table, which knows the maximum, leaves out; it never shows one from the neck's deep descent).

Force comes from an ``acquire.force.LoadSource`` interpolated onto the frames' times (NaN
where the source has no sample around a frame: never extrapolated), the frame time being
seconds since the first frame with results, the load file's time base.
"""

import math
from dataclasses import dataclass

import numpy as np

from livedic.dic.tensile.properties import NECKING_DROP

__all__ = ["STRESS_STRAIN_COLUMNS", "StressStrainTable", "cross_section_mm2", "stress_strain_table",
           "stress_strain_rows", "plot_stress_strain", "add_stress_arguments", "stress_options_from_args",
           "StressOptions", "RECORDED_FORCE", "AREA_METADATA_KEY", "UniformElongationWatch", "NECKING_DROP",
           "force_coverage_notes"]

STRESS_STRAIN_COLUMNS = ("frame", "time_s", "force_N", "eng_strain", "eng_stress_MPa", "true_strain",
                         "true_stress_MPa")
RECORDED_FORCE = "recorded:/machine/force"   # StressOptions.load when the force is the recording's own channel
AREA_METADATA_KEY = "area_mm2"               # session metadata key of A0, when the session had a cross-section


def cross_section_mm2(*, area=None, width=None, thickness=None):
    """The original cross-section A0 (mm^2) from ``area`` or from ``width x thickness``.

    Raises
    ------
    ValueError
        Neither or both forms, one of width/thickness without the other, or a value that is not a
        positive finite number (one line naming the option).
    """
    if area is not None and (width is not None or thickness is not None):
        raise ValueError("give --area MM2 or --width MM --thickness MM, not both")
    if area is not None:
        return _positive("--area", area)
    if width is None and thickness is None:
        raise ValueError("the specimen's cross-section is needed: --area MM2, or --width MM --thickness MM")
    if width is None or thickness is None:
        missing = "--thickness" if width is not None else "--width"
        raise ValueError(f"{missing} is missing: a rectangular cross-section needs --width MM and --thickness MM")
    return _positive("--width", width) * _positive("--thickness", thickness)


def _positive(name, value):
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value) or value <= 0:
        raise ValueError(f"{name} {value!r}: must be a positive number (mm or mm^2)")
    return float(value)


@dataclass(frozen=True)
class StressStrainTable:
    """One row per frame with results (arrays of one length); ``uniform_frame`` is the row of maximum force.

    ``uniform_frame`` is -1 when no frame has a force: then every true value is NaN.
    """
    frame: np.ndarray
    time_s: np.ndarray
    force_N: np.ndarray
    eng_strain: np.ndarray
    eng_stress_MPa: np.ndarray
    true_strain: np.ndarray
    true_stress_MPa: np.ndarray
    uniform_frame: int
    area_mm2: float

    def columns(self):
        """Ordered ``STRESS_STRAIN_COLUMNS`` -> array."""
        return {name: getattr(self, name) for name in STRESS_STRAIN_COLUMNS}


def stress_strain_table(frame, time_s, force_N, eng_strain, area_mm2):
    """Engineering and true stress and strain per frame.

    Parameters
    ----------
    frame, time_s : array_like (n,)
        Frame indices and times (s since the first frame).
    force_N, eng_strain : array_like (n,)
        Force (N; NaN where unknown) and the axial engineering strain (NaN where not read).
    area_mm2 : float
        Original cross-section A0, positive.

    Returns
    -------
    StressStrainTable
        ``eng_stress = F / A0``; ``true_strain = ln(1 + e)`` and ``true_stress = eng_stress x (1 + e)``
        up to and including the row of maximum force (the first one if tied), NaN after it
        (see the module notes).
    """
    area = _positive("area", float(area_mm2))
    force = np.asarray(force_N, dtype=np.float64)
    strain = np.asarray(eng_strain, dtype=np.float64)
    stress = force / area
    finite = np.isfinite(force)
    uniform = int(np.nanargmax(np.where(finite, force, -np.inf))) if finite.any() else -1
    with np.errstate(invalid="ignore", divide="ignore"):
        true_strain = np.log1p(strain)
        true_stress = stress * (1.0 + strain)
    past = np.arange(force.size) > uniform
    true_strain[past] = np.nan
    true_stress[past] = np.nan
    return StressStrainTable(np.asarray(frame, dtype=np.int64), np.asarray(time_s, dtype=np.float64), force, strain,
                             stress, true_strain, true_stress, uniform, area)


class UniformElongationWatch:
    """Live true strain and true stress, frame by frame, while the elongation may still be uniform.

    The offline table (``stress_strain_table``) ends the true values at the frame of maximum
    force; live that frame is known only once the force has fallen. Here they are given while
    the force is within ``drop`` (a fraction) of its running maximum, and NaN from the first
    frame below that on, for good (necking does not undo itself; an unloading is not uniform
    plastic flow either).

    Parameters
    ----------
    area_mm2 : float
        Original cross-section A0, positive.
    drop : float
        The fall below the running maximum force that ends the uniform elongation.
    """

    def __init__(self, area_mm2, drop=NECKING_DROP):
        self.area_mm2 = _positive("area", float(area_mm2))
        self.drop = float(drop)
        self.max_force_N = -math.inf
        self.ended = False              # the force has fallen below the running maximum: Ag is behind

    def __call__(self, force_N, eng_strain):
        """(true_strain, true_stress_MPa) of one frame: NaN where the force or strain is unknown, or past Ag."""
        nan = math.nan
        if not math.isfinite(force_N):
            return nan, nan
        if force_N < (1.0 - self.drop) * self.max_force_N:
            self.ended = True
        self.max_force_N = max(self.max_force_N, force_N)
        if self.ended or not math.isfinite(eng_strain) or eng_strain <= -1.0:
            return nan, nan
        return math.log1p(eng_strain), force_N / self.area_mm2 * (1.0 + eng_strain)


def force_coverage_notes(frame, time_s, force_N, eng_strain):
    """What a stress-strain table lacks, in words: no force at all, or the runs of frames with a strain and no force.

    Parameters
    ----------
    frame, time_s, force_N, eng_strain : array_like (n,)
        As ``stress_strain_table`` takes them.

    Returns
    -------
    list of str
        Empty when every frame with a strain has a force.
    """
    frame = np.asarray(frame)
    force = np.asarray(force_N, dtype=np.float64)
    strained = np.isfinite(np.asarray(eng_strain, dtype=np.float64))
    if frame.size == 0:
        return []
    times = np.asarray(time_s, dtype=np.float64)
    if not np.isfinite(force).any():
        return [f"no frame has a force: the force's times (seconds since the first frame with results) do not "
                f"cover the frames' {times[0]:g}-{times[-1]:g} s; check the load's time base and --load-offset"]
    missing = strained & ~np.isfinite(force)
    if not missing.any():
        return []
    edges = np.flatnonzero(np.diff(np.concatenate([[0], missing.astype(np.int8), [0]])))
    runs = [f"{frame[a]}" if b - a == 1 else f"{frame[a]}-{frame[b - 1]}" for a, b in zip(edges[0::2], edges[1::2])]
    shown = ", ".join(runs[:6]) + (f" and {len(runs) - 6} more" if len(runs) > 6 else "")
    return [f"no force at {int(missing.sum())} of {int(strained.sum())} frames with a strain (frames {shown}): "
            f"those frames have no stress; a property next to them is reported missing, never guessed"]


def stress_strain_rows(table, csv_rows):
    """The CSV text of ``table``: header then one line per frame, through the exporter's ``csv_rows``."""
    return ",".join(STRESS_STRAIN_COLUMNS) + "\n" + csv_rows(table.columns(), len(table.frame))


def plot_stress_strain(handle, table, *, title, properties=None):
    """Write the stress-strain plot (PNG) to ``handle``.

    The engineering curve over the frames with a force and a strain up to the fall at fracture
    (``dic.tensile.properties.fracture_frame``), the true curve up to uniform elongation (its last
    point marked Ag); with ``properties`` (``TensileProperties``) Rp0.2, Rm, ReH, ReL and the span
    of Ae are marked.
    """
    from matplotlib.figure import Figure

    from livedic.dic.tensile.properties import fracture_frame

    figure = Figure(figsize=(8, 5), dpi=100, layout="constrained")
    axes = figure.add_subplot()
    # the curve ends with the force's fall at fracture: the broken halves' frames after it (a simulator, or a
    # machine still moving) would only stretch the strain axis with the crack's opening at zero force
    broken = fracture_frame(table.eng_strain, table.eng_stress_MPa)
    shown = slice(None) if broken < 0 else slice(0, broken + 1)
    after = "" if broken < 0 or broken + 1 >= table.frame.size else \
        f" (ends at fracture, frame {int(table.frame[broken])}; {table.frame.size - broken - 1} later frames not drawn)"
    axes.plot(100.0 * table.eng_strain[shown], table.eng_stress_MPa[shown], marker=".", markersize=3, linewidth=1.2,
              label="engineering: F / A0 against (L - L0) / L0" + after)
    if table.uniform_frame >= 0 and np.isfinite(table.true_stress_MPa).any():
        axes.plot(100.0 * table.true_strain, table.true_stress_MPa, marker=".", markersize=3, linewidth=1.2,
                  label="true: F / A0 (1 + e) against ln(1 + e), up to Ag (maximum force)")
    if properties is not None:
        rp, rm = properties.Rp02_MPa, properties.Rm_MPa
        if math.isfinite(rp.value):
            axes.axhline(rp.value, color="0.5", linewidth=0.7, linestyle="--", label=f"Rp0.2 = {rp.value:.1f} MPa")
        if math.isfinite(rm.value):
            axes.plot([100.0 * rm.strain], [rm.value], marker="o", color="C3", linestyle="none",
                      label=f"Rm = {rm.value:.1f} MPa")
        _mark_yielding(axes, table, properties)
    axes.set_xlabel("strain (%)")
    axes.set_ylabel("stress (MPa)")
    axes.set_title(title, fontsize=10)
    axes.grid(True, alpha=0.3)
    if not (np.isfinite(table.eng_stress_MPa) & np.isfinite(table.eng_strain)).any():
        axes.text(0.5, 0.5, "no frame with both a force and an axial strain", ha="center", va="center",
                  transform=axes.transAxes, fontsize=10)
        axes.set_xlim(0, 1)
    else:
        axes.legend(loc="lower right", fontsize=9)
    figure.savefig(handle, format="png")


def _mark_yielding(axes, table, properties):
    """ReH and ReL as points, Ae as a bracket below ReL (only where they are values; frames index the table's rows)."""
    for item, name, marker, colour in ((properties.ReH_MPa, "ReH", "^", "C2"), (properties.ReL_MPa, "ReL", "v", "C4")):
        if math.isfinite(item.value) and item.frame >= 0:
            axes.plot([100.0 * table.eng_strain[item.frame]], [item.value], marker=marker, color=colour,
                      linestyle="none", label=f"{name} = {item.value:.1f} MPa")
    ae, rel = properties.Ae_percent, properties.ReL_MPa
    if math.isfinite(ae.value) and math.isfinite(rel.value):
        first, last = (100.0 * strain for strain in ae.strains)
        axes.annotate("", xy=(last, rel.value * 0.97), xytext=(first, rel.value * 0.97),
                      arrowprops={"arrowstyle": "<->", "color": "C4", "linewidth": 0.8})
        axes.plot([], [], color="C4", linewidth=0.8, label=f"Ae = {ae.value:.2f} % (yield point extension)")


# ----------------------------------------------------------------------------- command-line options

@dataclass(frozen=True)
class StressOptions:
    """What the stress-strain output needs: the load URI, its offset (s) and A0 (mm^2).

    ``load`` is ``RECORDED_FORCE`` when the force is the one recorded on ``/machine/force``
    (``recorded`` is True then): one value per tracked frame, no offset.
    """
    load: str
    offset_s: float
    area_mm2: float

    @property
    def recorded(self):
        return self.load == RECORDED_FORCE


def add_stress_arguments(parser, *, load_required=False):
    """Add ``--load --load-offset --area --width --thickness`` to an argparse parser."""
    group = parser.add_argument_group("force and stress (the stress-strain curve)")
    group.add_argument("--load", required=load_required, metavar="URI",
                       help="the testing machine's force: csv:FILE (header time_s,force_N, time_s in seconds since "
                            "the session's first frame); live sessions also tcp://HOST:PORT[?clock=sender] (text "
                            "lines force_N or time_s,force_N), modbus://HOST:PORT?register=N[&scale=K] (a PLC's "
                            "register, polled) and synthetic (the simulated test's own law)")
    group.add_argument("--load-offset", type=float, default=0.0, metavar="S",
                       help="shift the load file's times by S seconds (a sample at time_s belongs to the frame at "
                            "time_s + S; default 0)")
    group.add_argument("--area", type=float, metavar="MM2", help="original cross-section A0, mm^2")
    group.add_argument("--width", type=float, metavar="MM", help="specimen width, mm (with --thickness)")
    group.add_argument("--thickness", type=float, metavar="MM", help="specimen thickness, mm (with --width)")
    return parser


def stress_options_from_args(args, *, recorded_force=False, metadata=None):
    """``StressOptions`` from parsed arguments, or None without ``--load`` and cross-section options.

    Parameters
    ----------
    args : argparse.Namespace
    recorded_force : bool
        The recording holds force samples (``/machine/force``). Without ``--load`` they are the
        force then (``StressOptions.load`` is ``RECORDED_FORCE``), with A0 from ``--area`` or
        ``--width --thickness``, else from the session metadata's ``area_mm2``. With ``--load``
        the load wins (A0 from the options, else from the metadata too).
    metadata : dict, optional
        The recording's session metadata (for ``area_mm2``).

    Raises
    ------
    ValueError
        A cross-section without ``--load`` and without recorded force, ``--load`` without a
        cross-section, recorded force without any cross-section, a bad value, a load that is
        neither ``csv:FILE`` (offline, only a file holds a past test's force) nor the simulated
        test's own law (``synthetic:tensile?...``, the URI it was recorded with), or a non-finite
        offset: one line.
    """
    load = getattr(args, "load", None)
    section = {name: getattr(args, name, None) for name in ("area", "width", "thickness")}
    if load is None and getattr(args, "load_offset", 0.0):
        raise ValueError("--load-offset without --load: it shifts a force file's times, give --load csv:FILE")
    if load is None and recorded_force:
        return StressOptions(RECORDED_FORCE, 0.0, _recorded_area(section, metadata))
    if load is None:
        given = [f"--{name}" for name, value in section.items() if value is not None]
        if given:
            raise ValueError(f"{' '.join(given)} without --load csv:FILE: the stress needs the machine's force")
        return None
    if not str(load).strip().lower().startswith(("csv:", "synthetic:")):
        raise ValueError(f"--load {load!r}: a recording's force comes from a file here, give --load csv:FILE "
                         f"(header time_s,force_N), or the simulated test's own law, --load synthetic:tensile?...")
    offset = getattr(args, "load_offset", 0.0)
    if offset is None or not math.isfinite(offset):
        raise ValueError(f"--load-offset {offset!r}: must be a finite number of seconds")
    given = any(value is not None for value in section.values())
    if not given and (metadata or {}).get(AREA_METADATA_KEY) is not None:
        return StressOptions(str(load).strip(), float(offset), _recorded_area(section, metadata))
    return StressOptions(str(load).strip(), float(offset), cross_section_mm2(**section))


def _recorded_area(section, metadata):
    """A0 for the recorded force: the options when given, else the session's ``area_mm2``, else ValueError."""
    if any(value is not None for value in section.values()):
        return cross_section_mm2(**section)
    value = (metadata or {}).get(AREA_METADATA_KEY)
    if value is None:
        raise ValueError("this recording holds the machine's force (/machine/force) but not the specimen's "
                         "cross-section: give --area MM2, or --width MM --thickness MM")
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"the session's {AREA_METADATA_KEY} {value!r} is not a number: give --area MM2, "
                         f"or --width MM --thickness MM") from None
    return _positive(f"the session's {AREA_METADATA_KEY}", value)
