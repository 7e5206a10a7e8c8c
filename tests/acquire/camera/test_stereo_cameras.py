"""Two Aravis fake cameras as a stereo pair (acquire/stereo.py through ``stereo:aravis:...,aravis:...``): frames
pair by id with no mismatch, a frame lost in one view drops that pair only, one software trigger fires both.

Both views are Aravis's in-process fake (two devices opened from ``aravis:Fake_1``) in trigger mode: they expose on
the same clock ticks, as two cameras on one hardware trigger line (``InProcessFakeCamera(tick_hz=)``), and each
frame shows the scene at its tick, the tick number stamped in it. The right view's sensor region starts 40 px
further right: a different, known image of the same scene.
"""

from itertools import islice

import numpy as np
import pytest

from livedic.acquire.base import SourceError
from livedic.acquire.camera.aravis import open_uri
from livedic.acquire.camera.fake_gige import GigEFakeCamera
from livedic.acquire.camera.fake_genicam import InProcessFakeCamera
from livedic.acquire.camera.fake_motion import SpeckleMotion
from livedic.acquire.sources import open_stereo_source
from livedic.acquire.stereo import DropReason, StereoSource

pytestmark = [pytest.mark.usefixtures("aravis"), pytest.mark.time_limit(90)]

RIGHT_X = 40                      # the right view's region starts here: its image is the left's shifted 40 px
SIZE = (96, 128)                  # each view's region, rows x columns
STAMP = slice(RIGHT_X, RIGHT_X + 8)   # row 0 columns holding the tick number: seen by both views
RATE = 20                         # ticks per second: a 25 ms tolerance, wide for a loaded 2-core machine
N_PAIRS = 12


def view_uri(x, trigger="software"):
    return f"aravis:Fake_1?roi={x},0,{SIZE[1]},{SIZE[0]}&trigger={trigger}&frame_rate={RATE}&copy=1"


STEREO_URI = f"stereo:{view_uri(0)},{view_uri(RIGHT_X)}"


class Scene:
    """The specimen at tick k: a speckle motion, the tick number stamped in row 0 (picklable image_fn)."""

    def __init__(self):
        self.motion = SpeckleMotion((SIZE[0], SIZE[1] + RIGHT_X), step=(1, -1), max_displacement=16)

    def __call__(self, k):
        image = self.motion(k).copy()
        image[0, STAMP] = np.frombuffer(np.int64(k).tobytes(), np.uint8)
        return image


@pytest.fixture
def scene():
    scene = Scene()
    with InProcessFakeCamera(scene, tick_hz=RATE):
        yield scene


def tick_of(image, scene, x):
    """The tick a view's image shows, checked pixel for pixel against the scene at that tick."""
    k = int(np.frombuffer(np.ascontiguousarray(image[0, STAMP.start - x:STAMP.stop - x]).tobytes(), np.int64)[0])
    assert np.array_equal(image, scene(k)[:SIZE[0], x:x + SIZE[1]]), "not the scene at its stamped tick"
    return k


def check_pairs(pairs, scene):
    """Every pair's two images are of one tick (never a mismatch), each pair a later tick than the one before."""
    ticks = [(tick_of(p.left.image, scene, 0), tick_of(p.right.image, scene, RIGHT_X)) for p in pairs]
    assert all(left == right for left, right in ticks), f"mismatched pairs: {ticks}"
    assert all(a[0] < b[0] for a, b in zip(ticks, ticks[1:])), ticks


class Hiding:
    """A camera whose frames ``hidden`` (by the camera's index) never reach the pair: lost upstream (an id gap), or
    with ``renumber`` a missed trigger (no frame, no id)."""

    def __init__(self, camera, hidden, *, renumber=False):
        self.camera, self.hidden, self.renumber = camera, set(hidden), renumber

    def __getattr__(self, name):
        return getattr(self.camera, name)

    def __iter__(self):
        for frame in self.camera:
            if frame.index in self.hidden:
                continue
            if self.renumber:
                missed = sum(k < frame.index for k in self.hidden)
                frame = type(frame)(frame.index - missed, frame.timestamp_ns, frame.image, frame.pixel_format,
                                    frame.metadata)
            yield frame


def test_two_cameras_on_one_trigger_pair_frame_by_frame_and_the_software_trigger_fires_both(scene):
    with open_stereo_source(STEREO_URI) as pair_source:
        assert pair_source.trigger_rate_hz == RATE
        pairs = list(islice(pair_source, N_PAIRS))
    settings = pair_source.settings                               # closed: the trigger clock has stopped
    check_pairs(pairs, scene)
    indices = [p.index for p in pairs]
    assert indices[0] == 0 and all(a < b for a, b in zip(indices, indices[1:]))
    assert all(abs(p.skew_ns) <= 25_000_000 for p in pairs)
    assert settings["pairing"]["pairs"] == N_PAIRS
    # a camera started a tick early; on a loaded machine a fake may fill a frame a tick late (a missed trigger)
    assert {reason.partition(".")[2] for reason in settings["pairing"]["reasons"]} <= {"no_partner_in_time",
                                                                                     "timestamps_apart"}
    assert settings["pairing"]["tolerance_ms"] == 1e3 / RATE / 2
    # one clock fired both cameras, each tick once (Aravis's in-process fake exposes on its own ticks all the same)
    fired = settings["software_triggers"]
    assert fired >= 1 and settings["left"]["software_triggers"] == settings["right"]["software_triggers"] == fired
    for view in ("left", "right"):
        assert settings[view]["trigger"]["mode"] == "On" and settings[view]["trigger"]["source"] == "Software"


@pytest.mark.parametrize("renumber, reason", [(False, DropReason.PARTNER_LOST), (True, DropReason.TIMESTAMPS_APART)])
def test_a_frame_missing_in_one_view_drops_that_pair_only(scene, renumber, reason):
    left, right = open_uri(view_uri(0, "line:0")), open_uri(view_uri(RIGHT_X, "line:0"))
    with StereoSource(left, Hiding(right, {3, 7}, renumber=renumber)) as pair_source:
        pairs = list(islice(pair_source, N_PAIRS - 2))
        counts = pair_source.counts
    check_pairs(pairs, scene)
    first_right = pairs[0].right.index        # the right camera's frames 3 and 7 never came: those pairs dropped
    lost = {k - first_right for k in (3, 7) if k >= first_right}
    indices = [p.index for p in pairs]
    assert counts.dropped[("left", reason)] >= len(lost) and not lost & set(indices)    # gaps: the pairs dropped
    # exactly those, unless a camera started a tick early or a loaded machine made a fake fill a tick late
    others = {key for key in counts.dropped if key != ("left", reason)}
    assert {why for _, why in others} <= {DropReason.NO_PARTNER_IN_TIME, DropReason.TIMESTAMPS_APART}
    if not others:
        assert counts.dropped[("left", reason)] == counts.pairs_dropped == len(lost)
        assert indices == [k for k in range(N_PAIRS) if k not in lost]


def test_the_views_must_share_one_trigger(scene):
    with pytest.raises(SourceError, match="only the left view has trigger=software"):
        open_stereo_source(f"stereo:{view_uri(0)},{view_uri(RIGHT_X, 'free')}")
    with pytest.raises(SourceError, match="software trigger rates differ"):
        open_stereo_source(f"stereo:{view_uri(0)},{view_uri(RIGHT_X).replace(f'frame_rate={RATE}', 'frame_rate=10')}")


def test_a_camera_handed_over_to_the_pair_exposes_once_per_trigger_fired():
    # Aravis's GigE fake obeys TriggerSoftware (its in-process fake does not): no frame until the pair fires
    with GigEFakeCamera(SpeckleMotion(SIZE)) as fake:
        with open_uri(f"{fake.uri}?trigger=software&frame_rate={RATE}&copy=1") as camera:
            assert camera.hand_over_software_trigger() == RATE
            camera.start_acquisition()
            frames = iter(camera)
            for fired in range(1, 4):
                camera.fire_software_trigger()
                frame = next(frames)
                assert frame.index == fired - 1
            assert camera.settings["software_triggers"] == 3
        assert fake.served()["frames_served"] == 3


def test_a_camera_lost_mid_pair_ends_it_with_one_error_naming_that_view(scene):
    # Both fakes free-run at RATE on the wall clock's ticks; the right one, a GigE simulator, is then killed.
    with GigEFakeCamera(SpeckleMotion(SIZE)) as fake:
        right = f"{fake.uri}?frame_rate={RATE}&copy=1"
        with open_stereo_source(f"stereo:{view_uri(0, 'free')},{right}") as pair_source:
            pairs = iter(pair_source)
            assert len(list(islice(pairs, 3))) == 3
            fake.kill()
            with pytest.raises(SourceError) as lost:
                for _ in islice(pairs, 10 * RATE):
                    pass
    message = str(lost.value)
    assert message.startswith(f"right view ({right}): camera ") and " lost: " in message and "\n" not in message


# --------------------------------------------------------------------------- a rendered stereo pair, end to end

RENDERED = "synthetic:stereo?view={}&frames=6&size=160x160&focal=1500&strain=0&neck=0&w0=0.5&noise=0.5&pace=0"
TICK_STAMP = slice(0, 8)          # row 0, each view's first 8 columns (background): the tick, as in Scene


class RenderedPair:
    """Both views of the 3D simulator side by side (left | right), at tick k its frame ``k mod frames``, the tick
    stamped in each view's corner: two fakes cropping each half serve the two cameras of a rendered stereo rig."""

    def __init__(self):
        from livedic.acquire.simulator.stereo_source import SyntheticStereoViewSource
        views = []
        for view in ("left", "right"):
            source = SyntheticStereoViewSource(RENDERED.format(view))
            source.prepare()
            views.append([frame.image.copy() for frame in source])
            source.close()
        self.scene = source.scene
        self.frames = [np.hstack(pair) for pair in zip(*views)]
        self.width = views[0][0].shape[1]

    def __call__(self, k):
        image = self.frames[k % len(self.frames)].copy()
        stamp = np.frombuffer(np.int64(k).tobytes(), np.uint8)
        image[0, TICK_STAMP] = stamp
        image[0, self.width + TICK_STAMP.start:self.width + TICK_STAMP.stop] = stamp
        return image

    def displacement_mm(self, k0, k1):
        """The coupon's rigid 3D motion (mm, the left camera's frame) from the state shown at tick k0 to k1's."""
        centre = np.zeros((1, 2))
        n = len(self.frames)
        return (self.scene.positions(k1 % n, centre) - self.scene.positions(k0 % n, centre))[0]


def _tick(image):
    return int(np.frombuffer(np.ascontiguousarray(image[0, TICK_STAMP]).tobytes(), np.int64)[0])


@pytest.mark.time_limit(180)
def test_two_fakes_serving_a_rendered_stereo_pair_give_its_3d_motion_live(tmp_path):
    """Two Aravis fakes on one software trigger serve the 3D simulator's left and right views of a coupon moving
    towards and away from the cameras (0 to 0.5 mm); a live stereo session on them, given the rig's calibration,
    reads each frame's 3D motion from the reference, every frame's right view of the same tick as its left."""
    from livedic.acquire.recording.reader import read_results
    from livedic.acquire.recording.source import McapSource
    from livedic.stream.session.config import PointsConfig, SessionConfig, ViewerConfig
    from livedic.stream.session.session import Session
    from livedic.stream.stages.strain import StrainConfig
    scene = RenderedPair()
    height, width = scene.frames[0].shape[0], scene.width
    view = "aravis:Fake_1?roi={},0," + f"{width},{height}&trigger=software&frame_rate={RATE}&copy=1"
    record = tmp_path / "s.mcap"
    with InProcessFakeCamera(scene, tick_hz=RATE):
        config = SessionConfig(source=f"stereo:{view.format(0)},{view.format(width)}", frames=12,
                               viewer=ViewerConfig("none"), record=str(record), warm_up=False, static_frames=0,
                               rig=scene.scene.rig.calibration(), strain=StrainConfig(gauge_length=5.0),
                               points=PointsConfig(step=12))
        with Session(config) as session:
            session.prepare()
            session.start()
            session.run()
    left = {frame.index: _tick(frame.image) for frame in McapSource(str(record))}
    right = {frame.index: _tick(frame.image) for frame in McapSource(str(record), view="right")}
    assert left == right and len(left) == 12                      # every pair one tick, never mismatched
    results = read_results(str(record))
    reference_tick = left[results[0].frame_index]
    moving = 0
    for result in results[1:]:
        truth = scene.displacement_mm(reference_tick, left[result.frame_index])
        stereo = result.stereo
        ok = stereo["stereo_status"] == 0
        assert np.mean(ok) > 0.9
        measured = [np.mean(stereo[name][ok]) for name in ("u_mm", "v_mm", "w_mm")]
        np.testing.assert_allclose(measured, truth, atol=0.005)      # 5 um of 0-0.5 mm, at 160 px and f 1500 px
        moving += np.linalg.norm(truth) > 0.05
    assert moving >= 3                                                # the motion was there to be read
