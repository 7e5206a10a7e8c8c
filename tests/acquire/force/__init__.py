"""Tests of acquire.force (the folder mirrors the source)."""
