"""Tests of stream.output (the folder mirrors the source)."""
