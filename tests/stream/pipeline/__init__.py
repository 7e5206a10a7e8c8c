"""Tests of stream.pipeline (the folder mirrors the source)."""
