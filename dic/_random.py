"""Per-point random numbers for numba kernels.

The optimisers (PSO, WSO) run inside ``prange`` loops. numba's ``np.random``
state is per thread, so results would depend on how points are scheduled. Each
point instead owns a SplitMix64 stream seeded from ``(seed, point index)``: the
same seed gives the same numbers on any number of threads.
"""

import numpy as np
from numba import njit, uint64

_GOLDEN = uint64(0x9E3779B97F4A7C15)
_MIX1 = uint64(0xBF58476D1CE4E5B9)
_MIX2 = uint64(0x94D049BB133111EB)


@njit(cache=True)
def _mix(z):
    z = (z ^ (z >> uint64(30))) * _MIX1
    z = (z ^ (z >> uint64(27))) * _MIX2
    return z ^ (z >> uint64(31))


@njit(cache=True)
def new_state(seed, stream):
    """State array, shape (1,) uint64, for stream ``stream`` of ``seed``."""
    state = np.empty(1, dtype=np.uint64)
    state[0] = _mix(uint64(seed) * _GOLDEN + _mix(uint64(stream) + _GOLDEN))
    return state


@njit(cache=True)
def uniform(state):
    """Next float64 in [0, 1) from ``state`` (advanced in place)."""
    state[0] += _GOLDEN
    return (_mix(state[0]) >> uint64(11)) * (1.0 / 9007199254740992.0)
