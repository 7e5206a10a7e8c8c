"""A session's preparation (stream.session.preparation): what it opens, reads and places before any output.

The preparation reads the first frame and places the points, P0 and the strain stage on it, with its stages in
the order they run, and writes nothing; a bad force source is refused before the frame source opens, and the
session says where it stopped (its phase is the preparation's until its own outputs open).
"""

import numpy as np
import pytest

from livedic.stream.session.config import SessionConfig, ViewerConfig
from livedic.stream.session.preparation import Phase, Preparation
from livedic.stream.session.session import Session
from livedic.stream.stages.strain import StrainConfig

SOURCE = "synthetic:tensile?size=192x256&frames=3&pace=0"


def _config(**more):
    return SessionConfig(source=SOURCE, viewer=ViewerConfig("none"), record=None, warm_up=False,
                         strain=StrainConfig(gauge_length=100), **more)


def test_the_preparation_places_the_points_and_the_strain_on_the_first_frame_and_writes_nothing(tmp_path,
                                                                                                   monkeypatch):
    monkeypatch.chdir(tmp_path)
    said, events = [], []
    preparation = Preparation(_config(), say=said.append, event=lambda *event, **how: events.append(event))
    assert preparation.phase is Phase.CREATED
    preparation.run()
    try:
        assert preparation.phase is Phase.CHECKING_POINTS
        first = preparation.ahead.frame
        assert first.index == 0 and first.image.shape == (256, 192)
        points = preparation.points
        assert points.ndim == 2 and points.shape[1] == 2 and len(points) > 9
        assert np.allclose(points[0], preparation.p0.xy)                   # P0 is point 0
        # no --load, no --publish; the simulator's static frames' noise floor
        assert preparation.stages == [preparation.strain, preparation.noise_floor]
        assert [e.name for e in preparation.strain.extensometers] == ["axial", "transverse"]
        metadata = preparation.metadata({"fps": 50.0})
        assert metadata["source_settings"] == {"fps": 50.0} and metadata["extensometers"][0][0] == "axial"
        assert metadata["vsg_px"] == preparation.strain.vsg_px and metadata["area_mm2"] is None
        assert list(tmp_path.iterdir()) == []                             # no output before the session's own
    finally:
        preparation.source.close()


def test_a_bad_force_source_is_refused_before_the_frame_source_opens():
    session = Session(_config(load="csv:/nonexistent.csv"), say=lambda message: None)
    with pytest.raises(ValueError, match="/nonexistent.csv"):
        session.prepare()
    assert session.phase is Phase.CHECKING and session.source is None
    session.abandon()
    assert session.phase is Phase.CLOSED


def test_a_camera_or_a_pair_of_cameras_films_static_frames_a_file_or_the_simulator_holds_them():
    from livedic.stream.session.preparation import _films
    assert _films("aravis:CAM") and _films("stereo:aravis:CAM_L?trigger=line:1,aravis:CAM_R?trigger=line:1")
    assert not _films("synthetic:tensile") and not _films("images:frames/*.png")
    assert not _films("stereo:synthetic:stereo?view=left,synthetic:stereo?view=right")
    assert not _films("stereo:aravis:CAM_L,images:right/*.png")
