"""Part c of ``livedic bench strain``: the real muDIC dog-bone sequence, our axial extensometer against muDIC's."""

import csv
import glob
import math
import os
import time

import numpy as np

DOGBONE = "mudic_tensile_dogbone"
DOGBONE_MESH = (316, 523, 209, 1055)      # muDIC's mesh X1, X2, Y1, Y2 (its y upside down)
DOGBONE_GAUGE_PX = 600.0


def _mudic_nodes(folder):
    """muDIC's node positions (in its own, upside-down coordinates): {file stem: (N, 2)}."""
    with open(os.path.join(folder, "mudic_ref", "node_positions_subset.csv"), newline="") as handle:
        rows = list(csv.reader(handle))
    header, values = rows[0], np.array(rows[1:], dtype=np.float64)
    stems = [h[2:] for h in header if h.startswith("x_")]
    return {stem: np.column_stack([values[:, header.index(f"x_{stem}")], values[:, header.index(f"y_{stem}")]])
            for stem in stems}


def _bilinear_weights(grid_x, grid_y, x, y):
    """Indices and weights of the four nodes of a regular node grid around (x, y) (flattened row by row)."""
    i = int(np.clip(np.searchsorted(grid_x, x) - 1, 0, len(grid_x) - 2))
    j = int(np.clip(np.searchsorted(grid_y, y) - 1, 0, len(grid_y) - 2))
    fx = (x - grid_x[i]) / (grid_x[i + 1] - grid_x[i])
    fy = (y - grid_y[j]) / (grid_y[j + 1] - grid_y[j])
    return [(j, i, (1 - fx) * (1 - fy)), (j, i + 1, fx * (1 - fy)), (j + 1, i, (1 - fx) * fy), (j + 1, i + 1, fx * fy)]


def _mudic_extensometer(nodes, ends, height):
    """muDIC's true strain between our two reference ends (image rows), from its nodes interpolated bilinearly."""
    first = next(iter(nodes))                 # the reference frame's column comes first
    reference = nodes[first]
    grid_x, grid_y = np.unique(reference[:, 0]), np.unique(reference[:, 1])
    index = {(float(y), float(x)): n for n, (x, y) in enumerate(reference)}
    picks = []
    for x, y in ends:
        picks.append([(index[(float(grid_y[j]), float(grid_x[i]))], w)
                      for j, i, w in _bilinear_weights(grid_x, grid_y, x, height - 1 - y)])
    out = {}
    for stem, positions in nodes.items():
        a, b = (sum(w * positions[n] for n, w in pick) for pick in picks)
        out[stem] = float(np.hypot(*(b - a)))
    l0 = out[first]
    return {stem: math.log(length / l0) for stem, length in out.items()}


def dogbone_study(data, *, say):
    """Part c: the muDIC dog-bone sequence; rows per frame."""
    from livedic.acquire.files.image_file import read_grey_image
    from livedic.stream.session.config import TrackingConfig
    from livedic.stream.session.p0 import choose_p0
    from livedic.stream.session.points import build_points
    from livedic.dic.strain.extensometer import AXIAL, TRANSVERSE
    from livedic.stream.stages.strain import StrainConfig

    folder = os.path.join(data, DOGBONE)
    files = sorted(glob.glob(os.path.join(folder, "images", "ut_*.tif")))
    with open(os.path.join(folder, "mudic_ref", "strain_summary_all_frames.csv"), newline="") as handle:
        mean_strain = {row["file"]: float(row["mean_true_eyy"]) for row in csv.DictReader(handle)}
    images = [read_grey_image(path)[0] for path in files]
    height = images[0].shape[0]
    x1, x2, y1, y2 = DOGBONE_MESH
    roi = (x1, height - 1 - y2, x2 - x1 + 1, y2 - y1 + 1)
    tracking = TrackingConfig()
    p0 = choose_p0(images[0], roi, tracking.subset)
    points, roi, step = build_points(images[0].shape, roi=roi, step=None, n_points=1000, subset=tracking.subset,
                                     p0=p0.xy)
    stage = StrainConfig(gauge_length=DOGBONE_GAUGE_PX).place(points, p0=points[0], roi=roi, step=step,
                                                              subset=tracking.subset)
    axial = stage.placed.names.index(AXIAL)
    transverse = stage.placed.names.index(TRANSVERSE)
    ends = stage.extensometers[axial].ends
    reference_gauge = _mudic_extensometer(_mudic_nodes(folder), ends, height)
    say(f"c. real dog-bone (muDIC example, {len(files)} frames, every 5th of 86; a polymer coupon that necks): "
        f"{images[0].shape[1]}x{height}, ROI {','.join(str(v) for v in roi)} (muDIC's mesh rows {y1}..{y2} "
        f"upside down), {len(points):,} points every {step} px, P0 ({p0.xy[0]:g}, {p0.xy[1]:g}); {stage.describe()}")
    say(f"  {'file':10s} {'ok %':>6s} {'axial eng':>10s} {'axial true':>10s} {'transverse':>10s} "
        f"{'muDIC mean':>10s} {'muDIC gauge':>11s} {'ms':>6s}")
    tracker = tracking.tracker(images[0], points)
    rows = []
    for path, image in zip(files, images):
        name = os.path.basename(path)
        stem = os.path.splitext(name)[0]
        if image is images[0]:
            eng = true = trans = 0.0
            ok_share, ms, ok = 1.0, 0.0, True
        else:
            t0 = time.perf_counter()
            m = tracker.track(image)
            ms = 1e3 * (time.perf_counter() - t0)
            _, readings = stage.compute(m.u, m.v, m.ok)
            eng, true = float(readings.eng_strain[axial]), float(readings.true_strain[axial])
            trans = float(readings.eng_strain[transverse])
            ok_share, ok = float(m.ok.mean()), bool(readings.ok[axial])
        row = dict(file=name, ok_fraction=ok_share, axial_eng=eng, axial_true=true, transverse_eng=trans,
                   axial_ok=ok, mudic_mean_true_eyy=mean_strain.get(name, float("nan")),
                   mudic_gauge_true=reference_gauge.get(stem.replace("ut_", "ut"), float("nan")), track_ms=ms)
        rows.append(row)
        say(f"  {name:10s} {100 * ok_share:6.1f} {100 * eng:9.3f}% {100 * true:9.3f}% {100 * trans:9.3f}% "
            f"{100 * row['mudic_mean_true_eyy']:9.3f}% {100 * row['mudic_gauge_true']:10.3f}% {ms:6.0f}")
    values = np.array([r["axial_eng"] for r in rows])
    steps = np.diff(values)
    monotone = bool(np.all(np.isfinite(values)) and np.all(steps > 0))
    gauge = np.array([r["mudic_gauge_true"] for r in rows])
    ours = np.array([r["axial_true"] for r in rows])
    say(f"  axial extensometer {'monotone' if monotone else 'NOT monotone'} through the test (smallest step between "
        f"frames {100 * np.nanmin(steps):+.3f} %); final true strain {100 * ours[-1]:.3f} % vs muDIC "
        f"{100 * gauge[-1]:.3f} % between the same material points (max difference "
        f"{100 * np.nanmax(np.abs(ours - gauge)):.3f} %) and muDIC's mean over its whole mesh "
        f"{100 * rows[-1]['mudic_mean_true_eyy']:.3f} % (a longer gauge: a reference, not truth)")
    verdict = (f"{'MET' if monotone else 'NOT MET'}  target monotone axial extensometer strain through the real "
               f"dog-bone test: {'yes' if monotone else 'no'}, {len(rows)} frames, final "
               f"{100 * values[-1]:.2f} % engineering")
    return dict(rows=rows, monotone=monotone, verdict=verdict, gauge_px=stage.extensometers[axial].length_px)
