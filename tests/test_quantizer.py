"""The codebook's geometry (SPEC §1, §4): nearest, append, merge, mutual nearest pairs."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from avq.quantizer import _TREE_THRESHOLD, Codebook


def make(points, scale=1.0):
    cb = Codebook(len(points[0]), scale, capacity=2)
    for p in points:
        cb.append(np.asarray(p, dtype=float))
    return cb


def test_nearest_uses_the_per_dimension_scale():
    cb = make([(0.0, 0.0), (10.0, 0.0)], scale=(10.0, 1.0))
    # Unscaled, (4, 3) is nearer to (0, 0) (5 < 6.7); scaled by (10, 1) the distances are
    # sqrt(0.16 + 9) = 3.03 to the first and sqrt(0.36 + 9) = 3.06 to the second.
    i, d = cb.nearest(np.array([4.0, 3.0]))
    assert i == 0 and d == pytest.approx(np.sqrt(0.16 + 9))
    # With y weighted 100x less, x decides: (6, 3) is nearer to (10, 0).
    cb2 = make([(0.0, 0.0), (10.0, 0.0)], scale=(1.0, 100.0))
    assert cb2.nearest(np.array([6.0, 3.0]))[0] == 1
    assert cb2.distance(1, np.array([6.0, 3.0])) == pytest.approx(np.sqrt(16 + 0.0009))


def test_nearest_breaks_ties_by_lowest_index():
    cb = make([(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0)])
    assert cb.nearest(np.zeros(2)) == (0, 1.0)


def test_append_grows_past_capacity_and_keeps_vectors():
    pts = [(float(k), float(-k)) for k in range(10)]
    cb = make(pts)
    assert cb.size == 10 and np.array_equal(cb.vectors, np.array(pts))
    assert cb.append(np.array([5.5, 5.5])) == 10


def test_merge_replaces_a_pair_by_its_midpoint_and_returns_the_mapping():
    cb = make([(0, 0), (2, 0), (9, 9), (4, 2)])
    mapping = cb.merge([(1, 3)])
    assert mapping.tolist() == [0, 1, 2, 1]
    assert cb.vectors.tolist() == [[0, 0], [3, 1], [9, 9]]


def test_merge_of_two_pairs_shifts_later_indices_down():
    cb = make([(0, 0), (1, 0), (5, 0), (6, 0), (20, 0)])
    mapping = cb.merge([(2, 3), (0, 1)])
    assert mapping.tolist() == [0, 0, 1, 1, 2]
    assert cb.vectors.tolist() == [[0.5, 0], [5.5, 0], [20, 0]]


def test_merge_rejects_overlapping_or_bad_pairs():
    cb = make([(0, 0), (1, 0), (5, 0)])
    with pytest.raises(ValueError, match="disjoint"):
        cb.merge([(0, 1), (1, 2)])
    with pytest.raises(ValueError, match="distinct"):
        cb.merge([(0, 3)])


def test_mutual_nearest_pairs():
    # 0<->1 at 1; 2<->3 at 2 (2's other neighbour 1 is at 4).
    assert make([(0, 0), (1, 0), (5, 0), (7, 0)]).mutual_nearest_pairs().tolist() == [[0, 1], [2, 3]]


def test_not_mutual_means_no_pair():
    # 0's nearest is 1 (2 away), but 1's nearest is 2 (1 away): only (1, 2) is mutual.
    assert make([(0, 0), (2, 0), (3, 0)]).mutual_nearest_pairs().tolist() == [[1, 2]]


def test_a_tie_for_nearest_is_no_nearest_neighbour():
    # 0 has two neighbours at distance 1: it has no unique nearest, so nothing merges (Fig. 2's strict <).
    assert make([(0, 0), (1, 0), (-1, 0)]).mutual_nearest_pairs().tolist() == []


def test_mutual_nearest_pairs_use_the_scale():
    pts = [(0, 0), (0, 3), (4, 0)]
    assert make(pts).mutual_nearest_pairs().tolist() == [[0, 1]]
    assert make(pts, scale=(10.0, 1.0)).mutual_nearest_pairs().tolist() == [[0, 2]]


def test_batch_nearest_matches_single_queries_small_and_large():
    rng = np.random.default_rng(0)
    for n in (20, _TREE_THRESHOLD + 300):
        cb = make(rng.random((n, 3)).tolist(), scale=(1.0, 2.0, 0.5))
        xs = rng.random((200, 3))
        assert cb.nearest_batch(xs).tolist() == [cb.nearest(x)[0] for x in xs]


def test_neighbours_with_a_tree_match_the_dense_computation():
    rng = np.random.default_rng(1)
    pts = rng.random((_TREE_THRESHOLD + 50, 2))
    cb = make(pts.tolist())
    y = pts
    d = np.sqrt(((y[:, None] - y[None]) ** 2).sum(-1))
    np.fill_diagonal(d, np.inf)
    nn, d1, _ = cb.neighbours()
    assert np.array_equal(nn, d.argmin(1))
    assert np.allclose(d1, d.min(1))


def test_bad_scale_is_refused():
    with pytest.raises(ValueError, match="scale"):
        Codebook(2, (1.0, 0.0))


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(st.integers(0, 30), st.integers(0, 30)), min_size=2, max_size=40, unique=True),
    st.tuples(st.floats(0, 30), st.floats(0, 30)),
)
def test_nearest_is_the_true_argmin(points, query):
    cb = make([tuple(map(float, p)) for p in points], scale=(1.0, 3.0))
    q = np.array(query)
    d = np.sqrt((((np.array(points, float) - q) / (1.0, 3.0)) ** 2).sum(1))
    i, dist = cb.nearest(q)
    assert dist == pytest.approx(d.min())
    assert i == int(np.argmin(d))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 50), st.integers(0, 50)), min_size=2, max_size=40, unique=True))
def test_mutual_pairs_are_disjoint_and_mutual(points):
    cb = make([tuple(map(float, p)) for p in points])
    pairs = cb.mutual_nearest_pairs()
    flat = pairs.ravel().tolist()
    assert len(flat) == len(set(flat))
    y = np.array(points, float)
    d = np.sqrt(((y[:, None] - y[None]) ** 2).sum(-1))
    np.fill_diagonal(d, np.inf)
    for i, j in pairs:
        others_i = np.delete(d[i], [i, j])
        others_j = np.delete(d[j], [i, j])
        assert np.all(d[i, j] < others_i) and np.all(d[i, j] < others_j)
    before = cb.vectors.copy()
    mapping = cb.merge(pairs)
    for i, j in pairs:
        assert np.allclose(cb.vectors[mapping[i]], (before[i] + before[j]) / 2)
        assert mapping[i] == mapping[j]
