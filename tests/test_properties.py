"""Property-based tests (hypothesis) of the codebook and of the AVQ agent's invariants.

1. ``Codebook.nearest`` / ``nearest_batch`` return the true arg-min of the scaled distance
   (lowest index on exact ties, as ``numpy.argmin``), on both sides of the k-d tree threshold.
2. The agent never appends a vector within ``d_min`` (scaled) of a vector that existed when
   it was appended (SPEC §3), with merging off and, episode by episode, with merging on.
3. Merges (SPEC §4) replace each pair by its midpoint and mean profile, keep the other rows
   in order, and return a mapping that sends every old index to the row holding its data.
4. Action values stay finite under finite rewards.

Exact comparisons are made on dyadic grids (coordinates that are multiples of 1/2, scales that
are powers of two): there every scaled distance is computed exactly in float64, so exact ties
are real ties and the brute force can demand the lowest index. Arbitrary floats are compared
up to rounding.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings, strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, precondition, rule

from avq import AVQSarsa
from avq.agents.avq_sarsa import episode_end, kernels as core
from avq.quantizer import _TREE_THRESHOLD, Codebook, compact_rows, merge_kernel, mutual_nearest_pairs_kernel
from avq.rules import mean_square_difference, merge_profiles

from conftest import ScriptedEnv

FAST = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
LARGE = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])

# -- strategies -----------------------------------------------------------------------------------

POW2_SCALES = st.sampled_from([0.25, 0.5, 1.0, 2.0, 4.0])
half_grid = st.integers(-40, 40).map(lambda k: k / 2.0)  # exact dyadic coordinates
any_coord = st.floats(-50.0, 50.0, allow_nan=False, allow_infinity=False)


def brute_d2(vectors: np.ndarray, x: np.ndarray, inv_scale: np.ndarray) -> np.ndarray:
    """Squared scaled distances, with the same operations in the same order as ``nearest_index``."""
    z = (vectors - x) * inv_scale
    out = np.zeros(len(vectors))
    for d in range(vectors.shape[1]):
        out = out + z[:, d] * z[:, d]
    return out


def brute_argmin(vectors: np.ndarray, x: np.ndarray, scale) -> tuple[int, float]:
    inv = 1.0 / np.broadcast_to(np.asarray(scale, float), (vectors.shape[1],))
    d2 = brute_d2(vectors, x, inv)
    return int(np.argmin(d2)), float(np.sqrt(d2.min()))


def pairwise_scaled(y: np.ndarray, inv_scale: np.ndarray) -> np.ndarray:
    """Scaled pairwise distances, as ``neighbours_kernel`` computes them (scale first, then subtract)."""
    s = y * inv_scale
    diff = s[:, None, :] - s[None, :, :]
    d2 = np.zeros(diff.shape[:2])
    for d in range(y.shape[1]):
        d2 = d2 + diff[:, :, d] * diff[:, :, d]
    return np.sqrt(d2)


def brute_mutual_pairs(y: np.ndarray, inv_scale: np.ndarray) -> list[tuple[int, int]]:
    """Pairs i < j that are each other's unique (strictly) nearest vector."""
    p = len(y)
    if p < 2:
        return []
    d = pairwise_scaled(y, inv_scale)
    np.fill_diagonal(d, np.inf)
    nn = d.argmin(1)
    unique = np.array([(d[i] == d[i, nn[i]]).sum() == 1 for i in range(p)])
    return [(i, int(nn[i])) for i in range(p) if nn[i] > i and unique[i] and unique[nn[i]] and nn[nn[i]] == i]


# -- 1. nearest is the true arg-min ------------------------------------------------------------------


@FAST
@given(
    st.lists(st.tuples(half_grid, half_grid), min_size=1, max_size=60),
    st.lists(st.tuples(half_grid, half_grid), min_size=1, max_size=20),
    st.tuples(POW2_SCALES, POW2_SCALES),
)
def test_nearest_and_dense_batch_are_the_exact_argmin_with_lowest_index_on_ties(points, queries, scale):
    # Duplicates and equidistant vectors are allowed: ties must go to the lowest index.
    y = np.array(points, float)
    cb = Codebook.from_vectors(y, scale)
    xs = np.array(queries, float)
    expected = [brute_argmin(y, x, scale) for x in xs]
    for x, (i, dist) in zip(xs, expected):
        assert cb.nearest(x) == (i, dist)
    assert cb.nearest_batch(xs).tolist() == [i for i, _ in expected]


@FAST
@given(
    st.lists(st.tuples(any_coord, any_coord, any_coord), min_size=1, max_size=50),
    st.lists(st.tuples(any_coord, any_coord, any_coord), min_size=1, max_size=10),
    st.tuples(*[st.floats(1e-2, 1e2)] * 3),
)
def test_nearest_and_dense_batch_minimise_the_scaled_distance_on_arbitrary_floats(points, queries, scale):
    y = np.array(points, float)
    cb = Codebook.from_vectors(y, scale)
    xs = np.array(queries, float)
    inv = 1.0 / np.array(scale)
    batch = cb.nearest_batch(xs)
    for x, b in zip(xs, batch):
        d = np.sqrt((((y - x) * inv) ** 2).sum(1))
        i, dist = cb.nearest(x)
        assert i == brute_argmin(y, x, scale)[0]  # same arithmetic: exact agreement
        assert dist == pytest.approx(d.min(), rel=1e-12, abs=1e-12)
        # The batch path scales before subtracting: it may differ only within rounding.
        assert d[b] <= d.min() * (1 + 1e-9) + 1e-12


def large_grid_codebook(draw, n_min=_TREE_THRESHOLD + 1, n_max=_TREE_THRESHOLD + 200):
    """A codebook of distinct integer points, larger than the tree threshold, in random order."""
    n = draw(st.integers(n_min, n_max))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    side = draw(st.integers(int(np.ceil(np.sqrt(n))) + 1, 80))
    cells = rng.choice(side * side, size=n, replace=False)
    return np.stack([cells % side, cells // side], axis=1).astype(float), rng, side


@st.composite
def large_case(draw):
    y, rng, side = large_grid_codebook(draw)
    scale = draw(st.tuples(POW2_SCALES, POW2_SCALES))
    # Half-integer queries: often equidistant from two or four vectors.
    xs = rng.integers(-2, 2 * side + 2, size=(draw(st.integers(1, 64)), 2)) / 2.0
    return y, scale, xs


@LARGE
@given(large_case())
def test_tree_batch_path_minimises_the_scaled_distance(case):
    y, scale, xs = case
    cb = Codebook.from_vectors(y, scale)
    assert cb.size > _TREE_THRESHOLD
    inv = 1.0 / np.array(scale)
    batch = cb.nearest_batch(xs)
    for x, b in zip(xs, batch):
        d2 = brute_d2(y, x, inv)
        assert d2[b] == d2.min()  # a nearest vector (exact on this grid), ties aside


# The smallest failing case: 513 vectors (k, 0) and a query half-way between the first two.
LINE_513 = (np.stack([np.arange(513.0), np.zeros(513)], axis=1), (1.0, 1.0), np.array([[0.5, 0.0]]))


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@example(case=LINE_513)
@given(large_case())
def test_tree_batch_path_breaks_ties_by_lowest_index_like_nearest(case):
    y, scale, xs = case
    cb = Codebook.from_vectors(y, scale)
    expected = [brute_argmin(y, x, scale)[0] for x in xs]
    assert [cb.nearest(x)[0] for x in xs] == expected
    assert cb.nearest_batch(xs).tolist() == expected


@LARGE
@given(st.data())
def test_tree_mutual_nearest_pairs_match_the_brute_force(data):
    y, _, _ = large_grid_codebook(data.draw, n_max=_TREE_THRESHOLD + 80)
    scale = data.draw(st.tuples(POW2_SCALES, POW2_SCALES))
    cb = Codebook.from_vectors(y, scale)
    expected = brute_mutual_pairs(y, 1.0 / np.array(scale))
    assert [tuple(p) for p in cb.mutual_nearest_pairs().tolist()] == expected
    assert [tuple(p) for p in mutual_nearest_pairs_kernel(y, len(y), 1.0 / np.array(scale)).tolist()] == expected


# -- 1 and 3 together: random sequences of appends, merges and queries ----------------------------------


class CodebookMachine(RuleBasedStateMachine):
    """A Codebook and a value table, against a plain-list model of both (SPEC §1, §4)."""

    def __init__(self) -> None:
        super().__init__()
        self.scale = (1.0, 2.0)
        self.cb = Codebook(2, self.scale, capacity=1)
        self.model_y: list[tuple[float, float]] = []
        self.model_q: list[list[float]] = []

    @rule(x=st.tuples(half_grid, half_grid), q=st.lists(st.integers(-8, 8).map(float), min_size=3, max_size=3))
    def append(self, x, q):
        idx = self.cb.append(np.array(x))
        assert idx == len(self.model_y)
        self.model_y.append(x)
        self.model_q.append(q)

    def _apply_merge(self, pairs):
        old_y, old_q = np.array(self.model_y), np.array(self.model_q)
        mapping = self.cb.merge(pairs)
        n_new = len(old_y) - len(pairs)
        assert self.cb.size == n_new
        q_new = np.zeros((n_new, old_q.shape[1]))
        np.add.at(q_new, mapping, old_q)  # each new row: the mean of the old rows mapped to it
        q_new /= np.bincount(mapping, minlength=n_new)[:, None]
        check_merge_result(old_y, old_q, [tuple(sorted(p)) for p in pairs], mapping, self.cb.vectors, q_new)
        self.model_y = [tuple(v) for v in self.cb.vectors.tolist()]
        self.model_q = q_new.tolist()

    @precondition(lambda self: len(self.model_y) >= 2)
    @rule(rho=st.sampled_from([0.5, 4.0, 100.0]))
    def merge_mutual_similar(self, rho):
        pairs = [
            (i, j)
            for i, j in self.cb.mutual_nearest_pairs().tolist()
            if mean_square_difference(np.array(self.model_q[i]), np.array(self.model_q[j])) < rho
        ]
        assert [tuple(p) for p in self.cb.mutual_nearest_pairs().tolist()] == brute_mutual_pairs(
            np.array(self.model_y), 1.0 / np.array(self.scale)
        )
        self._apply_merge(pairs)

    @precondition(lambda self: len(self.model_y) >= 2)
    @rule(data=st.data())
    def merge_any_disjoint_pairs(self, data):
        perm = data.draw(st.permutations(range(len(self.model_y))))
        k = data.draw(st.integers(0, len(perm) // 2))
        # Either order within a pair: Codebook.merge sorts them.
        pairs = [(perm[2 * t], perm[2 * t + 1]) for t in range(k)]
        self._apply_merge(pairs)

    @precondition(lambda self: len(self.model_y) >= 1)
    @rule(x=st.tuples(half_grid, half_grid))
    def query(self, x):
        x = np.array(x)
        y = np.array(self.model_y)
        i, dist = brute_argmin(y, x, self.scale)
        assert self.cb.nearest(x) == (i, dist)
        assert self.cb.nearest_batch(x[None])[0] == i

    @invariant()
    def vectors_match_the_model(self):
        assert self.cb.vectors.tolist() == [list(v) for v in self.model_y]


CodebookMachine.TestCase.settings = settings(max_examples=40, stateful_step_count=25, deadline=None)
TestCodebookSequences = CodebookMachine.TestCase


# -- 3. merges ------------------------------------------------------------------------------------------


def expected_mapping(p: int, pairs) -> np.ndarray:
    removed = {j for _, j in pairs}
    mapping = np.empty(p, np.int64)
    w = 0
    for r in range(p):
        if r not in removed:
            mapping[r] = w
            w += 1
    for i, j in pairs:
        mapping[j] = mapping[i]
    return mapping


def check_merge_result(old_y, old_q, pairs, mapping, new_y, new_q):
    """Each pair (i < j) -> one row holding the midpoint and the mean profile; the others keep
    their data, in order; ``mapping[old]`` is the row now holding old's data."""
    p, n_new = len(old_y), len(old_y) - len(pairs)
    assert mapping.shape == (p,)
    assert mapping.tolist() == expected_mapping(p, pairs).tolist()
    assert len(new_y) == n_new and len(new_q) == n_new
    assert sorted(set(mapping.tolist())) == list(range(n_new))  # onto the new rows
    partner = {i: j for i, j in pairs} | {j: i for i, j in pairs}
    for r in range(p):
        if r in partner:
            i, j = sorted((r, partner[r]))
            assert new_y[mapping[r]].tolist() == ((old_y[i] + old_y[j]) / 2.0).tolist()
            assert new_q[mapping[r]].tolist() == ((old_q[i] + old_q[j]) / 2.0).tolist()
        else:
            assert new_y[mapping[r]].tolist() == old_y[r].tolist()
            assert new_q[mapping[r]].tolist() == old_q[r].tolist()
    kept = [r for r in range(p) if r not in {j for _, j in pairs}]
    assert mapping[kept].tolist() == list(range(n_new))  # the survivors keep their order


@st.composite
def codebook_and_values(draw, max_p=30):
    p = draw(st.integers(2, max_p))
    m = draw(st.integers(1, 4))
    y = np.array(draw(st.lists(st.tuples(half_grid, half_grid), min_size=p, max_size=p)), float)
    q = np.array(draw(st.lists(st.lists(st.floats(-1e6, 1e6), min_size=m, max_size=m), min_size=p, max_size=p)), float)
    return y, q


@FAST
@given(codebook_and_values(), st.data())
def test_merge_kernel_and_compact_rows_keep_data_and_remap_consistently(yq, data):
    y, q = yq
    p = len(y)
    perm = data.draw(st.permutations(range(p)))
    k = data.draw(st.integers(0, p // 2))
    pairs = sorted(tuple(sorted((perm[2 * t], perm[2 * t + 1]))) for t in range(k))
    extra = data.draw(st.integers(0, 3))  # spare capacity rows must not matter
    V = np.vstack([y, np.full((extra, 2), 7.0)])
    Q = np.vstack([q, np.full((extra, q.shape[1]), 7.0)])
    arr = np.array(pairs, np.int64).reshape(-1, 2)
    for i, j in pairs:  # the values rule, as the merge pass applies it before compacting (SPEC §4)
        merge_profiles(Q[i], Q[j], Q[i])
    mapping = merge_kernel(V, p, arr)
    n_new = compact_rows(Q, mapping)
    assert n_new == p - k
    check_merge_result(y, q, pairs, mapping, V[:n_new], Q[:n_new])


@FAST
@given(codebook_and_values(), st.floats(0.0, 1e3), st.sampled_from([0, 0, 1, 3]), st.data())
def test_merge_pass_merges_exactly_the_similar_mutual_pairs(yq, rho, merge_age, data):
    y, q = yq
    p, m = q.shape
    scale = np.array(data.draw(st.tuples(POW2_SCALES, POW2_SCALES)))
    episodes = data.draw(st.integers(0, 6))
    born = np.array(data.draw(st.lists(st.integers(0, episodes), min_size=p, max_size=p)), np.int64)
    q = q / 1e5 * data.draw(st.sampled_from([1.0, 1e5]))  # small profiles merge more often
    cap = p + 3
    V = np.zeros((cap, 2))
    V[:p] = y
    Q = np.zeros((cap, m))
    Q[:p] = q
    E = np.ones((cap, m))
    B = np.zeros((cap, 2 + m), np.int64)
    B[:p, 0] = born
    seen = np.array(data.draw(st.lists(st.integers(0, episodes), min_size=p, max_size=p)), np.int64)
    B[:p, 1] = seen
    counts = np.array(data.draw(st.lists(st.integers(0, 50), min_size=p * m, max_size=p * m)), np.int64)
    B[:p, 2:] = counts.reshape(p, m)
    act = np.zeros(cap + 1, np.int64)
    act[0] = min(p, 2)
    act[1:3] = [0, 1]
    pc = np.zeros((cap + 1, 2), np.int64)
    pc[0, 0] = -1  # no cached pairs
    inv = 1.0 / scale
    P = np.zeros(core.N_P)
    P[core.FloatParam.RHO] = rho
    IP = np.zeros(core.N_IP, np.int64)
    IP[core.IntParam.MERGE_AGE] = merge_age
    S = np.zeros(core.N_S, np.int64)
    S[core.SIZE] = p
    S[core.EPISODES] = episodes

    pairs = [
        (i, j)
        for i, j in brute_mutual_pairs(y, inv)
        if mean_square_difference(q[i], q[j]) < rho
        and (merge_age == 0 or (episodes - born[i] >= merge_age and episodes - born[j] >= merge_age))
    ]
    n = episode_end.merge_pass(V, Q, E, B, act, pc, inv, P, IP, S)
    assert n == len(pairs)
    n_new = p - n
    assert S[core.SIZE] == n_new
    mapping = expected_mapping(p, pairs)
    check_merge_result(y, q, pairs, mapping, V[:n_new], Q[:n_new])
    for r in range(p):
        merged = any(r in pr for pr in pairs)
        assert B[mapping[r], 0] == (episodes if merged else born[r])
        partner = [j if i == r else i for i, j in pairs if r in (i, j)]
        assert B[mapping[r], 1] == (max(seen[r], seen[partner[0]]) if merged else seen[r])
        merged_counts = counts.reshape(p, m)[r] + (counts.reshape(p, m)[partner[0]] if merged else 0)
        assert B[mapping[r], 2:].tolist() == merged_counts.tolist()  # decision counts add up
    assert not Q[n_new:p].any()  # freed rows are cleared
    if n:  # a merge clears every trace
        assert not E[:p].any() and act[0] == 0


# -- 2 and 4. the agent on random scripted episodes -------------------------------------------------------

LOW, HIGH = -10.0, 10.0
obs_coord = st.one_of(
    st.integers(-20, 20).map(lambda k: k / 2.0),  # grid: exact distance ties
    st.floats(LOW, HIGH, allow_nan=False),
)
obs_st = st.tuples(obs_coord, obs_coord)
reward_st = st.integers(-10, 10).map(float)


@st.composite
def episodes_st(draw, max_episodes=4, max_steps=12, reward=reward_st):
    out = []
    for _ in range(draw(st.integers(1, max_episodes))):
        start = draw(obs_st)
        raw = draw(st.lists(st.tuples(obs_st, reward, st.booleans()), min_size=1, max_size=max_steps))
        truncate_at_end = draw(st.booleans())
        steps = []
        for t, (x, r, collision) in enumerate(raw):
            last = t == len(raw) - 1
            steps.append((x, r, last and not truncate_at_end, last and truncate_at_end, collision))
        out.append((start, steps))
    return out


@st.composite
def agent_params(draw):
    kw = dict(
        alpha=draw(st.sampled_from([0.1, 0.5, 1.0])),
        lam=draw(st.sampled_from([0.0, 0.7, 1.0])),
        gamma=draw(st.sampled_from([0.9, 1.0])),
        epsilon=draw(st.sampled_from([0.0, 0.2, 1.0])),
        d_min=draw(st.sampled_from([0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0])),
        rho=draw(st.sampled_from([0.0, 1.0, 50.0, 1e9])),
        chi=draw(st.sampled_from([-4.0, -50.0])),
        q_init=draw(st.sampled_from([0.0, 5.0])),
        traces=draw(st.sampled_from(["replacing", "accumulating"])),
        value_trigger=draw(st.sampled_from([None, 0.5, 3.0])),
        reward_trigger=draw(st.sampled_from([None, 0.5, 4.0])),
        n_actions=draw(st.integers(1, 4)),
    )
    # The metric's scale, known exactly: given, or taken as high - low of obs_bounds.
    if draw(st.booleans()):
        scale = np.array(draw(st.tuples(POW2_SCALES, POW2_SCALES)))
        kw["scale"] = scale.tolist()
    else:
        bounds = draw(st.sampled_from([(LOW, HIGH), (-1.0, 1.0), (0.0, 4.0)]))
        kw["obs_bounds"] = [bounds, bounds]
        scale = np.full(2, bounds[1] - bounds[0])
    return kw, scale


def make_agent(episodes, kw, **over):
    kw = dict(kw, **over)
    env = ScriptedEnv(episodes, n_actions=kw.pop("n_actions"), low=LOW, high=HIGH)
    return AVQSarsa(env, seed=0, **kw)


def assert_spaced(rows: np.ndarray, first_new: int, inv_scale: np.ndarray, d_min: float) -> None:
    """Every row from ``first_new`` on is farther than d_min from every row before it."""
    for k in range(max(first_new, 1), len(rows)):
        z = (rows[:k] - rows[k]) * inv_scale
        dist = np.sqrt(z[:, 0] * z[:, 0] + z[:, 1] * z[:, 1])  # the agent's arithmetic
        assert dist.min() > d_min, (k, rows[k].tolist(), rows[int(dist.argmin())].tolist(), float(dist.min()))


@FAST
@given(episodes_st(), agent_params(), st.integers(1, 3))
def test_appended_vectors_keep_d_min_apart_without_merging(episodes, params, reps):
    kw, scale = params
    agent = make_agent(episodes, kw, merge_every=0)
    agent.learn(total_episodes=len(episodes) * reps)
    cb = agent.codebook_
    assert cb[0].tolist() == list(episodes[0][0])  # y_1 = x_0
    # Without merges vectors never move and are appended at the end, so every pair (i < j) was
    # (existing, appended) when j arrived.
    assert_spaced(cb, 1, 1.0 / scale, agent.d_min)
    seen = {tuple(x) for _, steps in episodes for x, *_ in steps}
    assert all(tuple(v) in seen for v in cb[1:].tolist())  # appended vectors are observations


@FAST
@given(episodes_st(), agent_params(), st.integers(1, 3), st.sampled_from([1, 2]))
def test_appended_vectors_keep_d_min_from_the_codebook_they_join_with_merging(episodes, params, reps, every):
    kw, scale = params
    agent = make_agent(episodes, kw, merge_every=every)
    before_merge: list[np.ndarray] = []
    end_episode = agent._end_episode

    def spy():  # the codebook at the end of the episode, before its merge pass
        before_merge.append(agent.codebook_)
        return end_episode()

    agent._end_episode = spy
    seen = {tuple(x) for _, steps in episodes for x, *_ in steps}
    for e in range(len(episodes) * reps):
        start = agent.codebook_ if e else np.asarray([episodes[0][0]], float)
        agent.learn(total_episodes=1)
        rows = before_merge[-1]
        assert rows[: len(start)].tolist() == start.tolist()  # nothing moves during an episode
        assert_spaced(rows, len(start), 1.0 / scale, agent.d_min)
        assert all(tuple(v) in seen for v in rows[len(start) :].tolist())
        assert agent.history_[e]["n_cells"] == len(rows) - agent.history_[e]["merges"] == agent.n_cells


@FAST
@given(
    episodes_st(max_episodes=3, max_steps=40, reward=st.floats(-1e3, 1e3)),
    agent_params(),
    st.integers(1, 4),
    st.sampled_from([0, 1]),
)
def test_values_stay_finite(episodes, params, reps, every):
    kw, _ = params
    agent = make_agent(episodes, kw, merge_every=every)
    agent.learn(total_episodes=len(episodes) * reps)
    q = agent.q_
    assert q.shape == (agent.n_cells, agent.n_actions)
    assert np.isfinite(q).all(), q
    assert np.isfinite(agent.codebook_).all()
