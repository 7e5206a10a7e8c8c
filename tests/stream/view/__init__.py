"""Tests of stream.view (the folder mirrors the source)."""
