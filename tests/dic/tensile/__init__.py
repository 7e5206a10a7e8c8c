"""Tests of dic.tensile (the folder mirrors the source)."""
