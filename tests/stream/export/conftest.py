"""Helpers shared by the export tests."""

import os

import pytest


def partial_files(folder):
    """The temporary files (``.livedic-*``) an unfinished write would leave anywhere under ``folder``."""
    return [os.path.join(top, name) for top, _, names in os.walk(folder) for name in names
            if name.startswith(".livedic-")]


# A stereo tensile test on the simulated rig with the simulator's force (--load synthetic): 0.5 mm away from the
# cameras and a 1 degree turn over the test, no neck (the force law is the uniform part's), 1 % strain.
STEREO_VIEW = ("synthetic:stereo?view={}&frames=50&size=384x384&focal=3000&strain=0.01&neck=0&w0=0.5&roty=1"
               "&noise=0.5&pace=0")
STEREO_PAIR = f"stereo:{STEREO_VIEW.format('left')},{STEREO_VIEW.format('right')}"


@pytest.fixture(scope="session")
def stereo_recording(tmp_path_factory):
    """The path of a recorded stereo session with --load synthetic and a 10 mm axial extensometer."""
    from livedic.stream.session.config import PointsConfig, SessionConfig, ViewerConfig
    from livedic.stream.session.session import Session
    from livedic.stream.stages.strain import StrainConfig
    path = str(tmp_path_factory.mktemp("stereo") / "stereo.mcap")
    config = SessionConfig(source=STEREO_PAIR, viewer=ViewerConfig("none"), record=path, warm_up=False,
                           strain=StrainConfig(gauge_length=10.0), points=PointsConfig(step=20), load="synthetic")
    with Session(config) as session:
        session.prepare()
        session.start()
        session.run()
    return path
