"""Tests of acquire.simulator (the folder mirrors the source)."""
