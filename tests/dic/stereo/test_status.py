"""Tests of dic/stereo/status.py: OK is 0 (what the recording's stereo_status means by ok) and every flag says why."""

from livedic.dic.stereo import StereoStatus


def test_ok_is_zero_and_every_flag_has_its_own_description():
    assert StereoStatus.OK == 0
    descriptions = [status.description for status in StereoStatus]
    assert all(isinstance(text, str) and text for text in descriptions)
    assert len(set(descriptions)) == len(descriptions)
