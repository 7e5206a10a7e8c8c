"""Tests of stream.publish (the folder mirrors the source)."""
