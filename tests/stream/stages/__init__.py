"""Tests of stream.stages (the folder mirrors the source)."""
