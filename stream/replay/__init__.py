"""Replay: a recording tracked again with other options, in order (``replay``) or on Dask (``parallel_replay``).

``rows`` makes the output rows of each replayed frame.
"""
