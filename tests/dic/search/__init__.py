"""Tests of dic.search: the contract shared by every integer search (test_search.py), then one module per search."""
