"""Replay: a recording tracked again with other options, in order (``replay``) or on Dask (``parallel_replay``).

``parameters`` resolves the method parameters (given, recorded, or ``livedic run``'s defaults), ``points``
the points (recorded, or rebuilt from the point options), ``agreement`` compares the replay with the
recording (``ReplayReport``, ``Agreement``), and ``rows`` makes the output rows of each replayed frame.
"""
