"""Tests of the benchmarks (livedic bench ...): plumbing and sanity, no timing asserted."""
