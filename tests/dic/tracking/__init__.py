"""Tests of dic.tracking (the folder mirrors the source)."""
