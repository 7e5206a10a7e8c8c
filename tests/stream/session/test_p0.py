"""Tests of stream/session/p0.py: P0 on the specimen's texture, never a hole or background, and why."""

import numpy as np
import pytest

from livedic.dic.speckle import SpecklePattern, render
from livedic.stream.session.p0 import P0_FLAT_SHARE, P0_WEAK_TEXTURE, P0Choice, P0Reason, choose_p0
from tests.stream.conftest import HOLE_CENTRE, HOLE_RADIUS, holed_image


def test_p0_moves_off_a_hole_at_the_centre_and_a_given_p0_there_is_weak():
    image = holed_image()
    subset = 21
    choice = choose_p0(image, None, subset)
    x, y = choice.xy
    assert choice.reason is P0Reason.MOVED_OFF_WEAK_CENTRE and choice.centre == (120.0, 100.0)
    # The whole subset (and its corners) is clear of the hole, and P0 is still near the centre.
    clearance = np.hypot(max(abs(x - HOLE_CENTRE[0]) - subset // 2, 0), max(abs(y - HOLE_CENTRE[1]) - subset // 2, 0))
    assert clearance > HOLE_RADIUS, choice        # the nearest pixel of P0's subset is outside the hole
    assert np.hypot(x - 120, y - 100) < HOLE_RADIUS + 2 * subset
    assert not choice.weak and choice.warning() is None
    assert "is not on specimen texture" in choice.describe() and f"({x:g}, {y:g})" in choice.describe()
    given = choose_p0(image, None, subset, p0=(121.2, 99.7))
    assert given.reason is P0Reason.GIVEN and given.xy == (121.0, 100.0) and given.weak
    assert given.flat_share > 0.9 and "given with --p0 is on weak texture" in given.warning()
    elsewhere = choose_p0(image, None, subset, p0=(30, 30))
    assert not elsewhere.weak and elsewhere.warning() is None


def test_p0_stays_near_the_centre_on_plain_speckle_and_blank_images_say_so():
    image = render(SpecklePattern((160, 200), n_speckles=700, radius=3.0, seed=9), bit_depth=8)
    choice = choose_p0(image, (20, 20, 160, 120), 21)
    assert choice.reason is P0Reason.BEST_NEAR_CENTRE and not choice.weak
    assert np.hypot(choice.xy[0] - 100, choice.xy[1] - 80) <= 21
    blank = choose_p0(np.full((100, 120), 80, np.uint8), None, 21)
    assert blank.reason is P0Reason.NO_TEXTURE and blank.weak and blank.xy == blank.centre


def test_p0_is_chosen_only_where_it_is_allowed():
    """A region that leaves out the image's right half: P0 goes on its side, nearest the centre asked for."""
    image = render(SpecklePattern((160, 200), n_speckles=700, radius=3.0, seed=9), bit_depth=8)
    allowed = np.zeros(image.shape, dtype=bool)
    allowed[:, :90] = True
    choice = choose_p0(image, None, 21, allowed=allowed, centre=(120.0, 80.0))
    assert choice.xy[0] < 90 and choice.centre == (120.0, 80.0) and not choice.weak
    assert choice.radius >= 120 - 90 - 1                     # found beyond the first radius, the nearest allowed
    assert choose_p0(image, None, 21, allowed=allowed, centre=(120.0, 80.0)) == choice     # deterministic


def test_a_roi_too_small_for_a_subset_has_no_candidate():
    image = render(SpecklePattern((100, 100), n_speckles=300, radius=3.0, seed=2), bit_depth=8)
    choice = choose_p0(image, (0, 0, 5, 5), 21)          # no subset around these pixels fits the image
    assert choice.reason is P0Reason.NO_TEXTURE and choice.xy == (2.0, 2.0)


@pytest.mark.parametrize("relative, flat, weak", [
    (1.0, 0.0, False), (P0_WEAK_TEXTURE, P0_FLAT_SHARE, False),              # the limits are still fine
    (0.2, 0.0, True), (1.0, 0.3, True), (float("nan"), 0.0, True),
])
def test_weak_means_little_texture_or_a_flat_share(relative, flat, weak):
    choice = P0Choice((1.0, 2.0), P0Reason.BEST_NEAR_CENTRE, relative, flat, (1.0, 2.0), False, 21)
    assert choice.weak is weak
    assert (choice.warning() is None) is (not weak)
    if weak and relative != relative:
        assert "texture n/a the ROI's median" in choice.warning()


def test_the_description_names_the_point_and_why():
    best = P0Choice((10.0, 20.0), P0Reason.BEST_NEAR_CENTRE, 1.25, 0.0, (11.0, 19.0), False, 21)
    assert best.describe() == ("P0 = point 0 at (10, 20), the best-textured point within 21 px of the ROI centre "
                               "(11, 19) (texture 1.25x the ROI's median, 0 % of its subset flat)")
    blank = P0Choice((5.0, 5.0), P0Reason.NO_TEXTURE, float("nan"), 1.0, (5.0, 5.0), True)
    assert "the ROI has no textured subset" in blank.describe()
    given = P0Choice((5.0, 5.0), P0Reason.GIVEN, 1.0, 0.0, (9.0, 9.0), False)
    assert given.describe().endswith("given with --p0 (texture 1.00x the ROI's median, 0 % of its subset flat)")
