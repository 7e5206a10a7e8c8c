"""Tests of dic.region (the folder mirrors the source)."""
