"""Tests of dic.subpixel (the folder mirrors the source)."""
