"""Tests of dic/neighbours.py: the k nearest neighbours within reach, nearest first, and the typical spacing."""

import numpy as np
import pytest

from livedic.dic.neighbours import SPACING_REACH, neighbour_graph, typical_spacing


def _grid(step=10, n=12):
    axis = np.arange(n) * float(step)
    xs, ys = np.meshgrid(axis, axis)
    return np.column_stack([xs.ravel(), ys.ravel()])


def _brute_force(xy, k, max_distance):
    """The k nearest other points within max_distance, ties by lower index: the contract, the slow way."""
    lists = []
    for i, p in enumerate(xy):
        d2 = ((xy - p) ** 2).sum(axis=1)
        order = [j for j in np.lexsort((np.arange(len(xy)), d2)) if j != i and d2[j] <= max_distance ** 2]
        lists.append(order[:k])
    return lists


def test_grid_neighbours_are_the_8_neighbourhood():
    xy = _grid()
    start, index = neighbour_graph(xy)
    centre = 5 * 12 + 5
    got = {tuple(xy[j]) for j in index[start[centre]:start[centre + 1]]}
    assert got == {(50 + dx, 50 + dy) for dx in (-10, 0, 10) for dy in (-10, 0, 10) if dx or dy}
    assert typical_spacing(xy) == pytest.approx(10.0)


def test_points_across_a_gap_are_not_neighbours():
    left = _grid(10, 5)
    right = left + [200.0, 0.0]
    start, index = neighbour_graph(np.vstack([left, right]))
    for i in range(len(left)):
        assert np.all(index[start[i]:start[i + 1]] < len(left))


def test_one_point_has_no_neighbours():
    start, index = neighbour_graph([(3.0, 4.0)])
    assert start.tolist() == [0, 0] and index.size == 0


@pytest.mark.parametrize("k, max_distance", [(8, 30.0), (3, 30.0), (20, 12.0)])
def test_scattered_points_get_their_k_nearest_within_reach_nearest_first(k, max_distance):
    xy = np.random.default_rng(3).uniform(0, 200, size=(150, 2))
    start, index = neighbour_graph(xy, k=k, max_distance=max_distance)
    expected = _brute_force(xy, k, max_distance)
    assert start[0] == 0 and np.all(np.diff(start) >= 0) and start[-1] == index.size
    for i in range(len(xy)):
        assert index[start[i]:start[i + 1]].tolist() == expected[i]


def test_ties_are_broken_by_the_lower_index():
    # the centre of a plus sign has its 4 neighbours at exactly the same distance
    xy = np.array([(10.0, 10.0), (20.0, 10.0), (10.0, 0.0), (0.0, 10.0), (10.0, 20.0)])
    start, index = neighbour_graph(xy, k=2, max_distance=15.0)
    assert index[start[0]:start[1]].tolist() == [1, 2]


def test_the_default_reach_is_spacing_reach_times_the_typical_spacing():
    xy = _grid(10, 6)          # typical spacing 10: axis neighbours 2 steps away are in reach, 3 steps are not
    start, index = neighbour_graph(xy, k=50)
    corner = index[start[0]:start[1]]
    distances = np.hypot(*(xy[corner] - xy[0]).T)
    assert distances.max() <= SPACING_REACH * 10.0
    assert set(np.round(distances, 6)) == set(np.round([10, 20, np.sqrt(200), np.sqrt(500)], 6))


@pytest.mark.parametrize("k", [0, -1, 2.5, True])
def test_a_bad_k_is_refused(k):
    with pytest.raises(ValueError, match="k must be a positive integer"):
        neighbour_graph(_grid(10, 3), k=k)


def test_no_reach_gives_no_neighbours():
    start, index = neighbour_graph(_grid(10, 3), max_distance=0.0)
    assert start.tolist() == [0] * 10 and index.size == 0


def test_typical_spacing_of_too_few_or_coincident_points_is_inf():
    assert typical_spacing(np.empty((0, 2))) == np.inf
    assert typical_spacing([(1.0, 2.0)]) == np.inf
    assert typical_spacing([(1.0, 2.0), (1.0, 2.0)]) == np.inf


def test_typical_spacing_of_clustered_points_is_their_mean_spacing():
    # pairs 1 px apart on a 20 px grid: the nearest neighbour is 1 px, the typical spacing sqrt(area / N)
    centres = _grid(20, 6)
    xy = np.vstack([centres, centres + [1.0, 0.0]])
    extent = xy.max(axis=0) - xy.min(axis=0)
    assert typical_spacing(xy) == pytest.approx(np.sqrt(extent[0] * extent[1] / len(xy)))
