"""A pattern's intensity (I0 = 1, float64) under a displacement field: every pixel mapped back to the
reference (closed form, a 1-D Newton table, or Newton's method for any callable) and its spots summed there,
point-sampled or integrated over the pixel by Gauss-Legendre quadrature."""

import math

import numpy as np

from livedic.dic.speckle.fields import DisplacementField
from livedic.dic.speckle.kernels import (_ARRAYS, _SINUSOID, _TABLE, _TILE, _gather_tiles, _invert_1d_table,
                                         _splat_translation)


# Gauss-Legendre points per axis for pixel integration of non-translation fields.
GAUSS_LEGENDRE_ORDER = 4
# Inverse-map convergence: |X + U(X) - x| below this (px) for every pixel.
INVERSE_TOLERANCE = 1e-10
_MAX_NEWTON = 60
_FD_STEP = 1e-5


def _gauss_legendre(pixel_integration):
    if not pixel_integration:
        return np.zeros(1), np.ones(1)
    nodes, weights = np.polynomial.legendre.leggauss(GAUSS_LEGENDRE_ORDER)
    return 0.5 * nodes, 0.5 * weights


def _eval_callable(field, X, Y):
    try:
        result = field(X, Y)
    except ValueError:
        raise
    except Exception as exc:   # a user function failing on arrays: say so in one line
        raise ValueError(f"displacement callable failed on float arrays of shape {X.shape}: "
                         f"{type(exc).__name__}: {exc}") from exc
    try:
        U, V = result
    except (TypeError, ValueError):
        raise ValueError("displacement callable must return a pair (U, V), got "
                         f"{type(result).__name__}") from None
    out = []
    for name, comp in (("U", U), ("V", V)):
        comp = np.asarray(comp, dtype=np.float64)
        if comp.ndim == 0:
            comp = np.full(X.shape, float(comp))
        if comp.shape != X.shape:
            raise ValueError(f"displacement callable returned {name} of shape {comp.shape} for X of shape "
                             f"{X.shape}: return arrays shaped like X (or scalars)")
        out.append(comp)
    return out[0], out[1]


def _invert_callable(field, x, y):
    """Reference coordinates (X, Y) with X + U(X, Y) = x, by Newton with a finite-difference Jacobian.

    The Jacobian is reused while the residual falls at least 4x per step (chord
    method) and refreshed otherwise. Raises ValueError if det(I + grad U) <= 0
    at any iterate or the residual does not reach INVERSE_TOLERANCE.
    """
    X = x.copy()
    Y = y.copy()
    U, V = _eval_callable(field, X, Y)
    rx = X + U - x
    ry = Y + V - y
    a = b = c = d = det = None
    previous = np.inf
    for _ in range(_MAX_NEWTON):
        residual = max(float(np.max(np.abs(rx))), float(np.max(np.abs(ry))))
        if not math.isfinite(residual):
            raise ValueError("displacement callable returned NaN or infinite values: give a finite field")
        if residual <= INVERSE_TOLERANCE:
            return X, Y
        if det is None or residual > 0.25 * previous:
            Ux, Vx = _eval_callable(field, X + _FD_STEP, Y)
            Uy, Vy = _eval_callable(field, X, Y + _FD_STEP)
            a = 1.0 + (Ux - U) / _FD_STEP
            b = (Uy - U) / _FD_STEP
            c = (Vx - V) / _FD_STEP
            d = 1.0 + (Vy - V) / _FD_STEP
            det = a * d - b * c
            bad = ~(det > 0.0)
            if bad.any():
                r, q = np.unravel_index(int(np.argmax(bad)), bad.shape)
                raise ValueError(f"displacement field is not invertible: det(I + grad U) = {det[r, q]:.3g} <= 0 "
                                 f"near reference ({X[r, q]:.1f}, {Y[r, q]:.1f}); the map folds the material")
        previous = residual
        X -= (d * rx - b * ry) / det
        Y -= (a * ry - c * rx) / det
        U, V = _eval_callable(field, X, Y)
        rx = X + U - x
        ry = Y + V - y
    worst = np.unravel_index(int(np.argmax(np.abs(rx) + np.abs(ry))), rx.shape)
    raise ValueError(f"could not invert the displacement field at pixel (x={x[worst]:g}, y={y[worst]:g}) "
                     f"to {INVERSE_TOLERANCE:g} px: it is not invertible or not smooth there")


def _render_float(pattern, field, pixel_integration):
    """Float64 image (H, W) in units of I0 (no scale, noise or rounding)."""
    H, W = pattern.shape
    out = np.zeros((H, W))
    R, reach = pattern.radius, pattern.cutoff_px
    if field is None or (isinstance(field, DisplacementField) and field.kind == "translation"):
        u = 0.0 if field is None else field.params["u"]
        v = 0.0 if field is None else field.params["v"]
        pattern._check_inside(max(abs(u), abs(v)) - pattern._slack, f"translation ({u:g}, {v:g})")
        xs, ys = pattern._xs, pattern._ys
        grow = reach + 1.0   # a pixel-integrated spot reaches half a pixel further
        near = ((xs + u > -grow) & (xs + u < W - 1 + grow) & (ys + v > -grow) & (ys + v < H - 1 + grow))
        _splat_translation(np.ascontiguousarray(xs[near]), np.ascontiguousarray(ys[near]), u, v, R,
                           reach + (0.5 if pixel_integration else 0.0), pixel_integration, out)
        return out
    nodes, weights = _gauss_legendre(pixel_integration)
    slack = pattern._slack
    bounds = (-0.5 - slack, W - 0.5 + slack, -0.5 - slack, H - 0.5 + slack)
    n_ty = (H + _TILE - 1) // _TILE
    excess = np.zeros(n_ty)
    none = np.zeros((1, 1))
    if isinstance(field, DisplacementField):
        kind, p = field._kernel_params()
        table = none
        if kind == _SINUSOID:
            # A sinusoid depends on one coordinate: tabulate its inverse once per column (row) and node.
            A, k, phase, axis_y, dir_v = p
            n = H if axis_y != 0.0 else W
            coords = (np.arange(n, dtype=np.float64)[None, :] + nodes[:, None]).ravel()
            if (axis_y != 0.0) == (dir_v != 0.0):      # along its own axis: 1-D Newton
                t = np.empty(coords.shape[0])
                ok = np.empty(coords.shape[0], dtype=np.bool_)
                _invert_1d_table(coords, A, k, phase, t, ok)
                if not ok.all():
                    raise ValueError(f"could not invert {field!r} near coordinate {coords[np.argmin(ok)]:g}: "
                                     "lower its amplitude")
                shift = coords - t
            else:                                        # across: the displacement at the pixel itself
                shift = A * np.sin(k * coords + phase)
            kind, p, table = _TABLE, np.array([axis_y, dir_v]), shift.reshape(nodes.shape[0], n)
        _gather_tiles(kind, p, table, none, none, 1.0, nodes, weights, *pattern._tile_args(), *bounds,
                      out, excess)
        pattern._check_inside(float(np.max(excess)), repr(field))
        return out
    rows, cols = np.mgrid[0:H, 0:W].astype(np.float64)
    one_node, one_weight = np.zeros(1), np.ones(1)
    for qa, wa in zip(nodes, weights):
        for qb, wb in zip(nodes, weights):
            X, Y = _invert_callable(field, cols + qa, rows + qb)
            _gather_tiles(_ARRAYS, np.zeros(1), none, np.ascontiguousarray(X), np.ascontiguousarray(Y), wa * wb,
                          one_node, one_weight, *pattern._tile_args(), *bounds, out, excess)
            pattern._check_inside(float(np.max(excess)), "the displacement field")
    return out
