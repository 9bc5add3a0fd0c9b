"""The tile coder (Sutton's tiles3, Sutton & Barto 2018 §9.5.4) and the bounds it is laid over."""

from math import floor

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from avq.agents._spaces import resolve_bounds
from avq.tilecoding import TileCoder, tile_hash


def unit_coder(size=64, n_tilings=2):
    # [0, 1] in 2 tiles of width 0.5; in units of 1/n_tilings of a tile, q = floor(x * 2 * n_tilings).
    return TileCoder([(0.0, 1.0)], tiles_per_dim=2, n_tilings=n_tilings, size=size)


def test_one_dimension_two_tilings_by_hand():
    coder = unit_coder()
    # q = floor(4x); tiling 0: q // 2; tiling 1 (displaced half a tile): (q + 1) // 2.
    assert coder.coordinates(np.array([0.1])).tolist() == [[0, 0], [1, 0]]  # q = 0
    assert coder.coordinates(np.array([0.3])).tolist() == [[0, 0], [1, 1]]  # q = 1
    assert coder.coordinates(np.array([0.6])).tolist() == [[0, 1], [1, 1]]  # q = 2
    assert coder.coordinates(np.array([0.8])).tolist() == [[0, 1], [1, 2]]  # q = 3
    # Indices in order of first use.
    assert coder(np.array([0.1])).tolist() == [0, 1]
    assert coder(np.array([0.3])).tolist() == [0, 2]
    assert coder(np.array([0.6])).tolist() == [3, 2]
    assert coder(np.array([0.8])).tolist() == [3, 4]
    assert coder.n_used == 5 and coder.overflows == 0


def test_same_tile_shares_indices_and_a_tile_apart_shares_none():
    coder = unit_coder()
    a = coder(np.array([0.1]))
    assert coder(np.array([0.2])).tolist() == a.tolist()  # same tile in both tilings
    assert set(coder(np.array([0.6])).tolist()).isdisjoint(a.tolist())  # 0.5 = one tile further
    # Tiling 1's boundary is at 0.25 (half a tile): 0.24 and 0.26 share tiling 0's tile only.
    lo, hi = coder(np.array([0.24])), coder(np.array([0.26]))
    assert lo[0] == hi[0] and lo[1] != hi[1]


def test_two_dimensions_two_tilings_by_hand():
    # Widths 0.5 and 1.0; q = (floor(4 x0), floor(2 x1)); tiling 1 is displaced by (1, 3) half-tiles.
    coder = TileCoder([(0.0, 1.0), (0.0, 2.0)], tiles_per_dim=2, n_tilings=2, size=64)
    assert coder.coordinates(np.array([0.1, 0.1])).tolist() == [[0, 0, 0], [1, 0, 1]]  # q = (0, 0)
    assert coder.coordinates(np.array([0.3, 0.6])).tolist() == [[0, 0, 0], [1, 1, 2]]  # q = (1, 1)
    assert coder.coordinates(np.array([0.6, 1.2])).tolist() == [[0, 1, 1], [1, 1, 2]]  # q = (2, 2)
    assert coder(np.array([0.1, 0.1])).tolist() == [0, 1]
    assert coder(np.array([0.3, 0.6])).tolist() == [0, 2]
    assert coder(np.array([0.6, 1.2])).tolist() == [3, 2]


def test_displacements_are_asymmetric_1_3_5():
    # 4 tilings of one tile per dimension on [0, 1]^3: q = floor(4 x). Tiling t adds t * (1, 3, 5).
    coder = TileCoder([(0.0, 1.0)] * 3, tiles_per_dim=1, n_tilings=4, size=64)
    assert coder.coordinates(np.zeros(3)).tolist() == [
        [0, 0, 0, 0],
        [1, 0, 0, 1],  # (0 + 1) // 4, (0 + 3) // 4, (0 + 5) // 4
        [2, 0, 1, 2],  # 2 // 4, 6 // 4, 10 // 4
        [3, 0, 2, 3],  # 3 // 4, 9 // 4, 15 // 4
    ]

    # So tiling 1's boundary lies at 3/4 along dimension 0 but at 1/4 along dimension 1:
    # it is not the same partition shifted along the diagonal.
    def tiling1(x):
        return coder.coordinates(np.array(x))[1, 1:].tolist()

    assert tiling1([0.70, 0.5, 0.5]) != tiling1([0.80, 0.5, 0.5])
    assert tiling1([0.20, 0.5, 0.5]) == tiling1([0.30, 0.5, 0.5])
    assert tiling1([0.5, 0.20, 0.5]) != tiling1([0.5, 0.30, 0.5])
    assert tiling1([0.5, 0.70, 0.5]) == tiling1([0.5, 0.80, 0.5])


def test_index_hash_table_overflows_into_hashing_and_counts_it():
    coder = unit_coder(size=3)
    assert coder(np.array([0.1])).tolist() == [0, 1]
    assert coder(np.array([0.3])).tolist() == [0, 2]
    assert coder.full and coder.n_used == 3
    # (0, 1) is new: hashed. (1, 1) is known: index 2.
    assert coder(np.array([0.6])).tolist() == [tile_hash((0, 1)) % 3, 2] == [1, 2]
    assert coder.overflows == 1
    # Both tiles new: two overflows, and two tilings may now share an index.
    assert coder(np.array([0.8])).tolist() == [1, 1]
    assert coder.overflows == 3
    # As in tiles3, every lookup of an unstored tile counts, also a repeated one.
    coder(np.array([0.8]))
    assert coder.overflows == 5 and coder.n_used == 3


def test_readonly_hands_out_nothing():
    coder = unit_coder(size=3)
    assert coder(np.array([0.1]), readonly=True).tolist() == [-1, -1]
    assert coder.n_used == 0
    coder(np.array([0.1]))
    assert coder(np.array([0.3]), readonly=True).tolist() == [0, -1]
    coder(np.array([0.3]))
    # Full: an unseen tile reads as the index learning would use, and no overflow is counted.
    assert coder(np.array([0.6]), readonly=True).tolist() == [1, 2]
    assert coder.overflows == 0


def test_the_fallback_hash_is_fixed():
    # Saved agents depend on it: it must not change between Python versions or runs.
    assert tile_hash((0, 1)) == 4428793074834702424
    assert tile_hash((0, 1)) != tile_hash((1, 0))
    assert tile_hash((0, -1)) == tile_hash((0, -1))


def test_deterministic_across_coders():
    rng = np.random.default_rng(0)
    xs = rng.uniform(-1, 2, size=(300, 2))
    a = TileCoder([(0, 1), (0, 1)], 4, 8, size=100)
    b = TileCoder([(0, 1), (0, 1)], 4, 8, size=100)
    out_a = [a(x).tolist() for x in xs]
    out_b = [b(x).tolist() for x in xs]
    assert out_a == out_b and a.overflows == b.overflows > 0


def test_points_outside_the_bounds_get_tiles_beyond_the_edge():
    coder = unit_coder()
    assert coder.coordinates(np.array([-0.1])).tolist() == [[0, -1], [1, 0]]  # q = -1
    assert coder.coordinates(np.array([1.3])).tolist() == [[0, 2], [1, 3]]  # q = 5


def test_tiles_and_restore_round_trip():
    coder = unit_coder(size=4)
    for x in (0.1, 0.3, 0.6, 0.8, 0.9):
        coder(np.array([x]))
    copy = unit_coder(size=4)
    copy.restore(coder.tiles(), coder.overflows)
    assert copy.n_used == coder.n_used == 4 and copy.overflows == coder.overflows
    for x in np.linspace(-0.5, 1.5, 41):
        assert copy(np.array([x]), readonly=True).tolist() == coder(np.array([x]), readonly=True).tolist()
    with pytest.raises(ValueError, match="empty"):
        copy.restore(coder.tiles())
    with pytest.raises(ValueError, match="twice"):
        unit_coder().restore(np.array([[0, 0], [0, 0]]))


@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(bounds=[(0, 0)]), "bounds"),
        (dict(bounds=[(0, np.inf)]), "bounds"),
        (dict(bounds=[1, 2]), "bounds"),
        (dict(tiles_per_dim=0), "tiles_per_dim"),
        (dict(tiles_per_dim=1.5), "tiles_per_dim"),
        (dict(n_tilings=0), "n_tilings"),
        (dict(size=0), "size"),
    ],
)
def test_bad_arguments_are_named(kwargs, match):
    args = dict(bounds=[(0.0, 1.0)], tiles_per_dim=2, n_tilings=2, size=8) | kwargs
    with pytest.raises(ValueError, match=match):
        TileCoder(**args)


def test_bad_points_are_refused():
    coder = unit_coder()
    with pytest.raises(ValueError, match="shape"):
        coder(np.array([0.1, 0.2]))
    with pytest.raises(ValueError, match="finite"):
        coder(np.array([np.nan]))


def test_resolve_bounds_takes_the_space_and_overrides_it():
    space = gym.make("CartPole-v1").observation_space
    with pytest.raises(ValueError, match=r"dimension 1 .*obs_bounds"):
        resolve_bounds(space, None)
    low, high = resolve_bounds(space, [None, (-3, 3), None, (-3.5, 3.5)])
    assert low[1:].tolist() == [-3.0, float(space.low[2]), -3.5]
    assert low[0] == pytest.approx(-4.8) and high[1] == 3.0
    with pytest.raises(ValueError, match="4 entries"):
        resolve_bounds(space, [(-1, 1)])
    with pytest.raises(ValueError, match=r"obs_bounds\[1\]"):
        resolve_bounds(space, [None, (3, -3), None, None])


# -- agreement with Sutton's tiles3 --------------------------------------------------------------------
# The reference below is tiles3 as published by Sutton (IHT and tiles(); without its int arguments),
# kept short. With bounds starting at 0 and one tile per unit, its floats are our observations.


class _IHT:
    def __init__(self, size):
        self.size, self.dictionary = size, {}

    def getindex(self, obj):
        d = self.dictionary
        if obj in d:
            return d[obj]
        count = len(d)
        assert count < self.size  # the comparison stays below the overflow
        d[obj] = count
        return count


def _tiles3(iht, numtilings, floats):
    qfloats = [floor(f * numtilings) for f in floats]
    out = []
    for tiling in range(numtilings):
        tilingX2 = tiling * 2
        coords = [tiling]
        b = tiling
        for q in qfloats:
            coords.append((q + b) // numtilings)
            b += tilingX2
        out.append(iht.getindex(tuple(coords)))
    return out


@settings(max_examples=30, deadline=None)
@given(
    n_dims=st.integers(1, 4),
    n_tilings=st.sampled_from([1, 2, 4, 8, 16]),
    data=st.data(),
)
def test_agrees_with_tiles3(n_dims, n_tilings, data):
    tiles = 4
    coder = TileCoder([(0.0, float(tiles))] * n_dims, tiles_per_dim=tiles, n_tilings=n_tilings, size=10**6)
    iht = _IHT(10**6)
    point = st.lists(st.floats(-1.0, tiles + 1.0, allow_nan=False), min_size=n_dims, max_size=n_dims)
    for x in data.draw(st.lists(point, min_size=1, max_size=20)):
        assert coder(np.array(x)).tolist() == _tiles3(iht, n_tilings, x)
