"""Tests of stream.cli (the folder mirrors the source)."""
