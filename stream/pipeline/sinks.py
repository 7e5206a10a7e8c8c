"""What a session does with each tracked frame: the sinks of ``stream.session.session.Session``.

A sink is a callable ``sink(result, stats)`` (a ``stream.pipeline.frame_result.FrameResult``
and the running ``SessionStats``), called for every tracked frame, in order, in
the session's output thread, at its own pace (the tracking thread hands results
over and goes on: ``stream.pipeline.tracker_loop``). The measurement's own stages (strain,
strain out, force) run in the tracking thread instead (``stream.pipeline.stage.Stage``). Optional
attributes say how the session treats it:

``name``
    How a warning names it ("recording", "P0 check" ...).
``required``
    True when the session's output is the sink's (a replay's CSV): an error there
    ends the session and is raised. Any other sink that fails is switched off and
    reported, and the measurement goes on (a broken display must not stop a test).
``stage``
    Its row in the session's stage times (default: ``name``).

The Rerun view (``stream.view.logger.RerunLogger``, in a session run in a process of
its own: ``stream.view.process.ViewProcess``) is a sink as it is. More sinks plug in
the same way: ``Session(config, sinks=[...])``.
"""

import math

from typing import Any

import numpy as np

from livedic.dic.status import Status


def stereo_arrays(measurement: Any) -> dict[str, np.ndarray]:
    """A stereo measurement's 3D arrays as ``Recorder.write_results`` takes them (``STEREO_ARRAYS``); {} in 2D."""
    points = getattr(measurement, "points", None)
    if points is None:
        return {}
    xyz, uvw, right = points.xyz, points.displacement, measurement.right_xy
    return {"x_mm": xyz[:, 0], "y_mm": xyz[:, 1], "z_mm": xyz[:, 2], "u_mm": uvw[:, 0], "v_mm": uvw[:, 1],
            "w_mm": uvw[:, 2], "stereo_status": points.status.astype(np.int32), "right_x": right[:, 0],
            "right_y": right[:, 1]}


class RecordResults:
    """Writes each frame's results (and a drop event when the queue dropped frames) to a ``Recorder``.

    Parameters
    ----------
    recorder : acquire.recording.writer.Recorder
    method : str
        ``"search+subpixel"``, recorded with every result set.
    strain_window : int, optional
        The strain window (points a side), recorded with each strain field.
    load_source : str, optional
        The ``--load`` URI, recorded with each force sample (``result.force_N`` set by the load stage).

    The strain field and extensometer readings that the strain stage attached to the
    result (``result.strain``, ``result.extensometers``) are recorded with it.
    """
    name = "recording"
    stage = "record results"
    required = False

    def __init__(self, recorder, method, *, strain_window=None, load_source=None):
        self.recorder = recorder
        self.method = method
        self.strain_window = strain_window
        self.load_source = load_source
        self.reference_frame_index = None

    def __call__(self, result, stats):
        m = result.measurement
        frame = result.frame
        if result.is_reference:
            self.reference_frame_index = frame.index
        self.recorder.write_results(
            frame.index, frame.timestamp_ns, np.arange(m.u.size, dtype=np.uint32), m.x, m.y, m.u, m.v,
            m.zncc, m.ok, ux=m.ux, uy=m.uy, vx=m.vx, vy=m.vy, status=m.status.astype(np.int32),
            iterations=m.iterations, method=self.method, processing_ns=result.processing_ns,
            latency_ns=result.latency_ns, reference_frame_index=self.reference_frame_index,
            dropped_frames=result.dropped_since_last, **stereo_arrays(m))
        if result.strain is not None:
            self.recorder.write_strain(frame.index, frame.timestamp_ns, result.strain, window=self.strain_window)
        if result.extensometers is not None and len(result.extensometers.names):
            self.recorder.write_extensometers(frame.index, frame.timestamp_ns, result.extensometers)
        if result.force_N is not None:
            self.recorder.write_force(frame.index, frame.timestamp_ns, result.force_N, result.stress_MPa,
                                      source=self.load_source or "")
        if result.reference_update is not None:
            self.reference_frame_index = frame.index       # the frames after this one are measured against it
        if result.dropped_since_last:
            self.recorder.write_event("drop", f"{result.dropped_since_last} frame(s) dropped by the queue before "
                                      f"frame {frame.index} (total {result.dropped_total})", level="warning")


class ReferenceUpdates:
    """Reports each move of the reference (``dic.tracking.key_frames``) as a ``reference_update`` event, and counts them.

    Parameters
    ----------
    report : callable
        ``report(kind, message, level)``: the session's event (shown, recorded; said only when asked).
    """
    name = "reference updates"
    required = False

    def __init__(self, report):
        self.report = report
        self.updates = []              # (frame index, dic.tracking.key_frames.ReferenceUpdate)

    def __call__(self, result, stats):
        update = result.reference_update
        if update is None:
            return
        self.updates.append((result.frame.index, update))
        text = update.describe().replace(f"tracked frame {update.frame}", f"frame {result.frame.index}")
        self.report("reference_update", text, "warning" if update.lost else "info")

    def summary(self):
        """Count, lost points and the longest update (ms), for the session summary."""
        return {"reference_updates": len(self.updates),
                "reference_update_lost": sum(u.lost for _, u in self.updates),
                "reference_update_max_ms": max((1e3 * u.seconds for _, u in self.updates), default=None)}


class FractureWatch:
    """Reports a detected fracture (``dic.tensile.fracture``) as a ``fracture`` event (said, shown, recorded).

    Parameters
    ----------
    report : callable
        ``report(kind, message, level)``: the session's event.
    """
    name = "fracture"
    required = False

    def __init__(self, report):
        self.report = report
        self.fractures = []            # (frame index, dic.tensile.fracture.Fracture)

    def __call__(self, result, stats):
        if result.fracture is None:
            return
        self.fractures.append((result.frame.index, result.fracture))
        self.report("fracture", f"frame {result.frame.index}: {result.fracture.describe()}", "warning")

    def summary(self):
        """The fractures for the session summary: frame and points separated, or an empty list."""
        return {"fractures": [{"frame": frame, "lost": f.lost, "jump_px": f.jump_px,
                               "separated": int(f.separated.sum())} for frame, f in self.fractures]}


class P0Watch:
    """Warns once when P0 is lost or its ZNCC falls below ``refind_zncc``: its trace is then doubtful.

    Parameters
    ----------
    refind_zncc : float
        The session's ``--refind-zncc``.
    report : callable
        ``report(kind, message, level)``: the session's event (said, shown, recorded).
    """
    name = "P0 check"
    required = False

    def __init__(self, refind_zncc, report):
        self.refind_zncc = refind_zncc
        self.report = report
        self.warned = False

    def __call__(self, result, stats):
        if self.warned:
            return
        m = result.measurement
        if result.is_reference:
            if not m.ok[0]:        # never trackable (the set-up's P0 warning says why): nothing is lost later
                self.warned = True
                self.report("p0_weak", f"P0 ({m.x[0]:g}, {m.y[0]:g}) is not ok in the reference frame "
                                       f"({Status(int(m.status[0])).description}): it has no trace", "warning")
            return
        ok, zncc = bool(m.ok[0]), float(m.zncc[0])
        if ok and zncc >= self.refind_zncc:
            return
        self.warned = True
        what = "P0 was lost" if not ok else \
            f"P0's ZNCC fell to {zncc:.2f} (below --refind-zncc {self.refind_zncc:g})"
        self.report("p0_weak", f"{what} at frame {result.frame.index}: its trace may be wrong from there", "warning")


def _depth(dtype):
    return f"{dtype.itemsize * 8}-bit" if dtype.kind == "u" else str(dtype)


def bit_depth_change(reference_dtype, image_dtype, reference_name, image_name):
    """One line when an image's pixel type (numpy dtype) differs from the reference's (None when alike).

    Measured on pairs of the same speckle at 8 and 16 bits (tests/stream/session/test_session_bit_depth.py): the
    displacements agree, since ZNCC does not depend on the grey-level scale and the quality gates compare
    each image with itself (texture against the reference's own percentile), so the pair is measured and
    the change is only warned about: it usually means another camera setting or a converted file.
    """
    if reference_dtype == image_dtype:
        return None
    return (f"{image_name} is {_depth(image_dtype)} but {reference_name} is {_depth(reference_dtype)}: measured "
            f"anyway (ZNCC does not depend on the grey-level scale), but the grey levels of the two differ in "
            f"resolution; check both were taken with the same camera settings")


class BitDepthWatch:
    """Warns once when a frame's pixel type differs from the reference frame's (``bit_depth_change``).

    Parameters
    ----------
    report : callable
        ``report(kind, message, level)``: the session's event (said, shown, recorded).
    """
    name = "bit depth check"
    required = False

    def __init__(self, report):
        self.report = report
        self.reference = None          # (dtype, index) of the reference frame
        self.warned = False

    def __call__(self, result, stats):
        frame = result.frame
        if result.is_reference:
            self.reference = (frame.image.dtype, frame.index)
            return
        if self.warned or self.reference is None:
            return
        dtype, index = self.reference
        text = bit_depth_change(dtype, frame.image.dtype, f"the reference frame {index}", f"frame {frame.index}")
        if text is not None:
            self.warned = True
            self.report("bit_depth", text, "warning")


class ProgressLine:
    """The session's progress bar: frames acquired, fps, latency, drops, reconnections, error.

    Parameters
    ----------
    bar : stream.pipeline.progress.ProgressBar
    acquisition : stream.pipeline.acquisition.AcquisitionThread
        Its frame count and reconnections are shown.
    """
    name = "progress"
    required = False

    def __init__(self, bar, acquisition):
        self.bar = bar
        self.acquisition = acquisition
        self._last = None

    def __call__(self, result, stats):
        self._last = (result, stats)
        if self.bar.due():                 # the text (a percentile over every frame) only when it is shown
            self.bar.update(self.acquisition.frames, self.text(result, stats))

    def finish(self):
        """The last redraw, with the last result's numbers."""
        text = self.text(*self._last) if self._last is not None else self.bar.last_text
        self.bar.update(self.acquisition.frames, text, force=True)
        self.bar.close()

    def text(self, result, stats):
        """The line's numbers after ``result``."""
        text = (f"{stats.fps:5.1f} fps  latency p50 {stats.latency_ms(50):5.1f} ms  "
                f"drops {result.dropped_total}")
        if self.acquisition.reconnects:
            text += f"  reconnected {self.acquisition.reconnects}x"
        if math.isfinite(result.error_rms_px):
            text += f"  error {result.error_rms_px:.3f} px"
        readings = result.extensometers
        if readings is not None:
            for name, strain, ok in zip(readings.names[:2], readings.eng_strain, readings.ok):
                text += f"  {name} {100 * strain:.3f} %" if ok else f"  {name} lost"
        if result.force_N is not None:
            text += f"  {result.force_N:,.0f} N" if math.isfinite(result.force_N) else "  force n/a"
            if result.stress_MPa is not None and math.isfinite(result.stress_MPa):
                text += f" {result.stress_MPa:.0f} MPa"
        return text


class FunctionSink:
    """A plain function as a sink, with a ``name`` and whether it is ``required`` (see the module notes)."""

    def __init__(self, function, name, *, required=False):
        self.function = function
        self.name = name
        self.required = required

    def __call__(self, result, stats):
        self.function(result, stats)
