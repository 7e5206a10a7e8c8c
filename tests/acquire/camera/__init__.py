"""Tests of acquire.camera (the folder mirrors the source)."""
