"""Tests of acquire/recording/metadata.py: metadata to MCAP's string maps and back, types kept, nothing evaluated."""

import math
import pathlib

import numpy as np

from livedic.acquire.recording import metadata as md
from livedic.acquire.recording.schema import JSON_KEYS_KEY


def test_round_trip_keeps_json_types_and_strings():
    original = {"name": "run 1", "number": "42", "fps": 25.0, "count": 3, "on": True, "none": None,
                "roi": [1, 2, 3], "nested": {"a": [1.5, "x"]}}
    strings = md.metadata_to_strings(original)
    assert all(isinstance(v, str) for v in strings.values())
    assert strings["name"] == "run 1" and strings["number"] == "42"        # strings stored as they are
    assert md.metadata_from_strings(strings) == original                   # "42" stays a string, 3 an int


def test_numpy_paths_tuples_and_sets_become_json():
    strings = md.metadata_to_strings({"a": np.arange(3), "f": np.float32(0.5), "t": (1, 2), "s": {4},
                                      "p": pathlib.Path("/tmp/x.mcap"), 7: "key made a string"})
    back = md.metadata_from_strings(strings)
    assert back == {"a": [0, 1, 2], "f": 0.5, "t": [1, 2], "s": [4], "p": "/tmp/x.mcap", "7": "key made a string"}


def test_nan_stays_nan_and_unknown_objects_become_their_text():
    class Thing:
        def __str__(self):
            return "thing!"

    back = md.metadata_from_strings(md.metadata_to_strings({"nan": float("nan"), "thing": Thing()}))
    assert math.isnan(back["nan"]) and back["thing"] == "thing!"


def test_to_json_never_raises():
    loop = []
    loop.append(loop)
    assert md.to_json(loop) == '"[[...]]"'                                  # circular: its text, not an error
    assert md.to_json({"k": np.int64(3)}) == '{"k": 3}'


def test_reserved_key_is_written_once_and_never_returned():
    strings = md.metadata_to_strings({JSON_KEYS_KEY: "caller's value", "n": 1})
    assert strings[JSON_KEYS_KEY] == '["n"]'
    assert JSON_KEYS_KEY not in md.metadata_from_strings(strings)


def test_damaged_strings_stay_strings():
    assert md.metadata_from_strings({JSON_KEYS_KEY: "not json", "n": "1"}) == {"n": "1"}
    assert md.metadata_from_strings({JSON_KEYS_KEY: '{"n": 1}', "n": "1"}) == {"n": "1"}     # not a list
    assert md.metadata_from_strings({JSON_KEYS_KEY: '["n"]', "n": "{broken"}) == {"n": "{broken"}
    assert md.metadata_from_strings({"n": "[1]"}) == {"n": "[1]"}          # no key list: nothing is decoded
    deep = "[" * 100_000 + "]" * 100_000
    assert md.metadata_from_strings({JSON_KEYS_KEY: '["d"]', "d": deep}) == {"d": deep}
