"""Tests of stream.replay (the folder mirrors the source)."""
