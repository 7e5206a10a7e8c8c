"""The stage protocol (stream.pipeline.stage): the session's stages implement it, and their order is checked.

A stage that reads a field no earlier stage (nor the tracker) sets is refused, naming the stage that sets it
too late; the order ``Session.stages`` gives (strain, strain out, force) passes.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from livedic.acquire.force.source import LoadWarnings
from livedic.stream.pipeline.frame_result import RESULT_FIELDS, TRACKER_FIELDS
from livedic.stream.pipeline.stage import Reference, Stage, StageOrderError, check_stage_order
from livedic.stream.publish import PublishStage
from livedic.stream.session.config import SessionConfig, ViewerConfig
from livedic.stream.session.session import Session
from livedic.stream.stages.force import LoadStage
from livedic.stream.stages.strain import StrainConfig


def _stages():
    """(strain, publisher, load) as the session builds them, on a 9 x 9 grid of points."""
    axis = np.arange(100.0, 181.0, 10.0)
    points = np.array([(x, y) for y in axis for x in axis])
    strain = StrainConfig(gauge_length=60.0).place(points, p0=(140.0, 140.0), roi=(100, 100, 80, 80), step=10.0,
                                                   subset=21)
    publisher = PublishStage(SimpleNamespace(where="udp://127.0.0.1:9"), ["axial", "transverse"], None)
    load = LoadStage(SimpleNamespace(uri="csv:force.csv", warnings=LoadWarnings()), 10.0, None)
    return strain, publisher, load


def test_the_session_stages_implement_the_protocol_with_fields_of_the_frame_result():
    for stage in _stages():
        assert isinstance(stage, Stage)
        assert set(stage.needs) <= RESULT_FIELDS and set(stage.provides) <= RESULT_FIELDS
    assert set(TRACKER_FIELDS) <= RESULT_FIELDS


def test_the_session_order_passes_and_a_wrong_order_is_refused():
    strain, publisher, load = _stages()
    session = Session(SessionConfig(viewer=ViewerConfig("none"), record=None, warm_up=False))
    session.strain, session.publishers, session.load_stage = strain, [publisher], load
    assert session.stages == [strain, publisher, load]
    check_stage_order(session.stages)                       # what prepare checks
    with pytest.raises(StageOrderError, match="'force' needs 'extensometers', but stage 'strain' provides it after"):
        check_stage_order([load, strain])
    with pytest.raises(StageOrderError, match="publish udp://127.0.0.1:9' needs 'extensometers'"):
        check_stage_order([publisher, strain, load])
    with pytest.raises(StageOrderError, match="no stage provides it"):
        check_stage_order([load])


def test_a_field_that_is_not_in_the_frame_result_is_refused():
    class Typo(Stage):
        name = "typo"
        needs = ("extensometer",)

        def on_frame(self, result):
            pass

    with pytest.raises(StageOrderError, match="'extensometer' is not a FrameResult field"):
        check_stage_order([Typo()])


def test_a_stage_without_summary_or_metadata_gives_none_and_the_stages_give_theirs():
    class Quiet(Stage):
        name = "quiet"

        def on_frame(self, result):
            pass

    quiet = Quiet()
    quiet.on_reference(Reference(0, np.zeros((1, 2)), (0, 0, 1, 1), None, (1, 1)))
    assert quiet.summary_lines() == [] and quiet.metadata() == {}
    strain, publisher, load = _stages()
    assert strain.metadata()["extensometers"][0][0] == "axial" and load.metadata() == {"area_mm2": 10.0}
    assert strain.summary_lines()[0].startswith("  strain     engineering, window 5 points")
    assert load.summary_lines() == ["  force      csv:force.csv: no force at any frame"]
    assert publisher.summary_lines()[0].startswith("  publish    udp://127.0.0.1:9: 0 frames sent")


def test_the_load_and_publish_stages_count_time_from_the_reference_frame():
    strain, publisher, load = _stages()
    reference = Reference(3, np.zeros((1, 2)), (0, 0, 1, 1), 10, (200, 200), timestamp_ns=5_000_000_000)
    for stage in (strain, publisher, load):
        stage.on_reference(reference)
    assert publisher.first_ns == load.first_ns == 5_000_000_000
