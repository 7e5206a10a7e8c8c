"""The colour bars under the field views: an RGB image of the gradient with its limits written in black.

Text drawn into the image reads the same in Rerun's light and dark themes; ``LEGENDS`` says which limits
entity, unit and display factor each bar has.
"""

from __future__ import annotations

import numpy as np

from livedic.stream.view.entities import (
    LEGEND_EYY, LEGEND_U, LEGEND_V, LEGEND_W, LIMITS_EYY, LIMITS_U, LIMITS_V, LIMITS_W)

_BAR_WIDTH = 340
_BAR_MARGIN = 10
_BAR_GRADIENT_HEIGHT = 24
_BAR_TEXT_HEIGHT = 34
# colour bars: legend -> (the entity of its numeric limits, the unit on the bar, display factor)
LEGENDS = {LEGEND_U: (LIMITS_U, "px", 1.0), LEGEND_V: (LIMITS_V, "px", 1.0), LEGEND_EYY: (LIMITS_EYY, "%", 100.0),
           LEGEND_W: (LIMITS_W, "mm", 1.0)}


def colour_bar_image(lut: np.ndarray, lo: float, hi: float, unit: str = "px", factor: float = 1.0) -> np.ndarray:
    """RGB colour bar: the gradient from ``lo`` to ``hi`` over a white strip with the limits and 0 in black.

    The limits are written times ``factor`` in ``unit`` (strain: 100 and "%"). White margins left and
    right keep the labels of two bars side by side apart.
    """
    import cv2
    bar = np.full((_BAR_GRADIENT_HEIGHT + _BAR_TEXT_HEIGHT, _BAR_WIDTH, 3), 255, dtype=np.uint8)
    first, last = _BAR_MARGIN, _BAR_WIDTH - 1 - _BAR_MARGIN          # the gradient's end columns
    columns = np.arange(last - first + 1)
    bar[:_BAR_GRADIENT_HEIGHT, first:last + 1] = lut[(columns * lut.shape[0]) // columns.size][None, :, :]
    font, font_scale, thickness = cv2.FONT_HERSHEY_SIMPLEX, 0.62, 2
    baseline_y = _BAR_GRADIENT_HEIGHT + _BAR_TEXT_HEIGHT - 7
    black = (0, 0, 0)

    def tick(x: int) -> None:
        cv2.line(bar, (x, _BAR_GRADIENT_HEIGHT), (x, _BAR_GRADIENT_HEIGHT + 5), black, 2)

    def text_width(text: str) -> int:
        return cv2.getTextSize(text, font, font_scale, thickness)[0][0]

    left, right = f"{_fmt(lo * factor)} {unit}", f"{_fmt(hi * factor)} {unit}"
    left_end, right_start = first + text_width(left), last + 1 - text_width(right)
    cv2.putText(bar, left, (first, baseline_y), font, font_scale, black, thickness, cv2.LINE_AA)
    cv2.putText(bar, right, (right_start, baseline_y), font, font_scale, black, thickness, cv2.LINE_AA)
    tick(first)
    tick(last)
    if lo < 0 < hi:
        zero_x = first + int(round((0 - lo) / (hi - lo) * (last - first)))
        tick(zero_x)
        half = text_width("0") // 2
        if left_end + 6 < zero_x - half and zero_x + half + 6 < right_start:    # only where it does not overlap
            cv2.putText(bar, "0", (zero_x - half, baseline_y), font, font_scale, black, thickness, cv2.LINE_AA)
    return bar


def _fmt(value: float) -> str:
    if not np.isfinite(value):
        return "n/a"
    return f"{value:+.3g}" if abs(value) < 1000 else f"{value:+.0f}"
