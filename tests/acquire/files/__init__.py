"""Tests of acquire.files (the folder mirrors the source)."""
