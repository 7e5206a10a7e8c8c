"""Tests of dic.strain (the folder mirrors the source)."""
