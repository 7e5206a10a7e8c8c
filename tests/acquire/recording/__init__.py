"""Tests of acquire.recording (the folder mirrors the source)."""
