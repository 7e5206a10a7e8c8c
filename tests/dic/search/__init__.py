"""Tests of each integer search of dic.search, one module each (the contract shared by all: tests/dic/test_search.py)."""
