"""Tests of stream.session (the folder mirrors the source)."""
