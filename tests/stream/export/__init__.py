"""Tests of stream.export (the folder mirrors the source)."""
