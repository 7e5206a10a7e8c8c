"""Tests of dic.speckle (the folder mirrors the source)."""
