"""The compiled draws of avq._random give exactly what the agent's Generator would have given."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from numba import njit

from avq._random import RawStream, below, uniform


@njit(cache=True)
def _draw(src, kinds, ns, out):
    for k in range(kinds.shape[0]):
        out[k] = uniform(src) if kinds[k] == 0 else below(src, ns[k])


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    calls=st.lists(
        st.tuples(st.sampled_from([0, 1]), st.sampled_from([1, 2, 3, 4, 5, 7, 2**31 + 11, 2**32])),
        min_size=1,
        max_size=120,
    ),
    chunks=st.lists(st.integers(1, 25), min_size=1, max_size=10),
    size=st.integers(1, 64),
    syncs=st.lists(st.booleans(), min_size=1, max_size=10),
)
def test_draws_equal_the_generators_and_leave_it_where_it_would_be(seed, calls, chunks, size, syncs):
    # Mixed random() and integers(0, n) calls, in chunks with reserve() and syncs in between, against the
    # same calls on a twin Generator: the same numbers, and in the end the same generator state (so that a
    # fused loop drawing from the generator itself goes on from the same place).
    rng, twin = np.random.default_rng(seed), np.random.default_rng(seed)
    kinds = np.array([c[0] for c in calls])
    ns = np.array([c[1] for c in calls], dtype=np.int64)
    out = np.zeros(len(calls))
    stream = RawStream(rng, size=size)
    k = c = 0
    while k < len(calls):
        n = chunks[c % len(chunks)]
        stream.reserve(64)
        _draw(stream.src, kinds[k : k + n], ns[k : k + n], out[k : k + n])
        if syncs[c % len(syncs)]:
            stream.sync()
        k += n
        c += 1
    stream.sync()
    want = [twin.random() if kind == 0 else twin.integers(0, n) for kind, n in zip(kinds, ns)]
    assert out.tolist() == [float(w) for w in want]
    assert rng.bit_generator.state == twin.bit_generator.state


def test_integers_of_one_draw_nothing_and_numba_continues_the_stream():
    rng, twin = np.random.default_rng(7), np.random.default_rng(7)
    stream = RawStream(rng)
    stream.reserve()
    out = np.zeros(3)
    _draw(stream.src, np.array([1, 1, 0]), np.array([1, 1, 1]), out)
    stream.sync()
    assert out.tolist() == [0.0, 0.0, twin.random()]
    # The generator itself, through Numba (as the fused loops draw), continues where the stream stopped.

    @njit
    def next_two(g):
        return g.random(), g.integers(0, 5)

    assert next_two(rng) == next_two(twin)


def test_a_stream_needs_pcg64_and_reports_an_exhausted_buffer():
    with pytest.raises(TypeError, match="PCG64"):
        RawStream(np.random.Generator(np.random.MT19937(0)))
    stream = RawStream(np.random.default_rng(0), size=1)
    stream.reserve(1)
    out = np.zeros(3)
    with pytest.raises(RuntimeError, match="ran out"):
        _draw(stream.src, np.array([0, 0, 0]), np.array([1, 1, 1]), out)
