"""The baselines 'grid' (Sarsa(λ) on a fixed uniform grid) and 'tiles' (linear Sarsa(λ), tile coding)."""

import gymnasium as gym
import numpy as np
import pytest

import avq
from avq import AGENTS, GridSarsa, TileSarsa, make_agent

CARTPOLE_BOUNDS = [(-2.4, 2.4), (-3, 3), (-0.21, 0.21), (-3.5, 3.5)]


def mountain_car(**kw):
    return gym.make("MountainCar-v0", **kw)


def learned_state(agent):
    if isinstance(agent, TileSarsa):
        return agent.weights_, agent.tile_coder_.tiles()
    return agent.q_, agent.visited_


# -- registry and construction ---------------------------------------------------------------------------


def test_registered_by_name_with_their_defaults():
    assert AGENTS["grid"][0] is GridSarsa and AGENTS["tiles"][0] is TileSarsa
    for name in ("grid", "tiles"):
        cls, defaults = AGENTS[name]
        agent = make_agent(name, mountain_car(), seed=2)
        assert type(agent) is cls and agent.get_params() == {**defaults, "seed": 2}
        assert set(agent.get_params()) == set(cls._param_names())
    # Sutton & Barto's Mountain Car setting, but for epsilon (see the registry's comment).
    tiles = AGENTS["tiles"][1]
    assert (tiles["n_tilings"], tiles["alpha"], tiles["lam"], tiles["q_init"]) == (8, 0.5, 0.9, 0.0)
    # The class defaults are the registry's.
    for cls, defaults in (AGENTS["grid"], AGENTS["tiles"]):
        assert cls(mountain_car()).get_params() == {**defaults, "seed": None}


@pytest.mark.parametrize("name", ["grid", "tiles"])
def test_an_unbounded_dimension_asks_for_obs_bounds(name):
    with pytest.raises(ValueError, match=r"dimension 1 .*pass obs_bounds="):
        make_agent(name, "CartPole-v1")
    agent = make_agent(name, "CartPole-v1", obs_bounds=CARTPOLE_BOUNDS, seed=0).learn(total_episodes=3)
    assert agent.get_params()["obs_bounds"] == [list(map(float, b)) for b in CARTPOLE_BOUNDS]


@pytest.mark.parametrize("cls", [GridSarsa, TileSarsa])
def test_a_discrete_observation_space_points_to_tabular(cls):
    with pytest.raises(ValueError, match="'tabular'"):
        cls(gym.make("FrozenLake-v1"))


@pytest.mark.parametrize(
    "param,value,match",
    [
        ("alpha", 0.0, r"alpha must be in \(0.0, 1.0\]"),
        ("alpha", 1.5, "alpha"),
        ("lam", -0.1, "lam"),
        ("gamma", 1.1, "gamma"),
        ("epsilon", 2, "epsilon"),
        ("q_init", float("nan"), "q_init"),
        ("traces", "dutch", "traces"),
        ("seed", -3, "seed"),
        ("obs_bounds", [(0, 1)], "obs_bounds must have 2 entries"),
        ("obs_bounds", [(0, 1), (1, 0)], r"obs_bounds\[1\]"),
        ("obs_bounds", [(0, 1), "ab"], r"obs_bounds\[1\]"),
        ("obs_bounds", 3.0, "obs_bounds"),
    ],
)
@pytest.mark.parametrize("cls", [GridSarsa, TileSarsa])
def test_bad_shared_parameters_name_the_parameter(cls, param, value, match):
    with pytest.raises(ValueError, match=match):
        cls(mountain_car(), **{param: value})


@pytest.mark.parametrize(
    "param,value,match",
    [
        ("bins", 0, "bins"),
        ("bins", 2.5, "bins"),
        ("bins", [10, 0], "bins"),
        ("bins", [4, 4, 4], "bins must be an int or 2"),
        ("bins", 10_000, "bins gives 100000000 cells"),
    ],
)
def test_bad_grid_parameters_name_the_parameter(param, value, match):
    with pytest.raises(ValueError, match=match):
        GridSarsa(mountain_car(), **{param: value})


@pytest.mark.parametrize(
    "param,value,match",
    [
        ("n_tilings", 0, "n_tilings"),
        ("n_tilings", 2.0, "n_tilings"),
        ("tiles_per_dim", 0, "tiles_per_dim"),
        ("tiles_per_dim", [8], "tiles_per_dim must be an int or 2"),
        ("iht_size", 0, "iht_size"),
        ("iht_size", 4, r"iht_size must be at least n_tilings \(8\)"),
    ],
)
def test_bad_tile_parameters_name_the_parameter(param, value, match):
    with pytest.raises(ValueError, match=match):
        TileSarsa(mountain_car(), **{param: value})


# -- GridSarsa: the discretization ------------------------------------------------------------------------


def test_grid_bin_index_by_hand_with_clipping(scripted):
    # [-10, 10]^2 in 4 x 5 bins: widths 5 and 4; flat index = 5 k0 + k1.
    agent = GridSarsa(scripted([], dims=2), bins=[4, 5])
    obs = np.array(
        [
            [-10.0, -10.0],  # (0, 0)
            [-4.9, 3.9],  # 5.1 / 5 -> 1, 13.9 / 4 -> 3
            [0.0, 0.0],  # 10 / 5 = 2, 10 / 4 = 2.5 -> (2, 2)
            [7.4, -6.1],  # 17.4 / 5 -> 3, 3.9 / 4 -> 0
            [10.0, 10.0],  # the upper bound is in the last bin: (3, 4)
            [-50.0, 99.0],  # clipped to the edge bins: (0, 4)
        ]
    )
    assert agent.cells(obs).tolist() == [0, 8, 12, 15, 19, 4]


def test_grid_obs_bounds_replace_the_space_bounds_where_given(scripted):
    # Dimension 0 keeps [-10, 10] (2 bins of 10); dimension 1 becomes [0, 1] (2 bins of 0.5).
    agent = GridSarsa(scripted([], dims=2), bins=2, obs_bounds=[None, (0, 1)])
    assert agent.cells(np.array([[5.0, 0.6], [5.0, -3.0], [-5.0, 0.4], [-5.0, 7.0]])).tolist() == [3, 2, 0, 1]


# -- one Sarsa(λ) update by hand -------------------------------------------------------------------------

# Start at x0, one step to x1 with reward -1, then a step with reward 2 that terminates.
GRID_EPISODE = ([-5.0, -5.0], [([5.0, 5.0], -1.0, False, False, False), ([5.0, 6.0], 2.0, True, False, False)])
TILE_EPISODE = ([-7.0], [([-3.0], -1.0, False, False, False), ([6.0], 2.0, True, False, False)])


@pytest.mark.parametrize("traces", ["replacing", "accumulating"])
def test_grid_sarsa_update_by_hand(scripted, traces):
    # 2 x 2 bins on [-10, 10]^2: (-5, -5) is bin 0, (5, 5) is bin 3. alpha 0.5, gamma 0.9, lambda 0.8,
    # q_init 1. Both decisions are ties at q_init, so a0 and a1 are whatever the agent drew.
    env = scripted([GRID_EPISODE], dims=2)
    agent = GridSarsa(env, bins=2, alpha=0.5, lam=0.8, gamma=0.9, epsilon=0.0, q_init=1.0, traces=traces, seed=0)
    agent.learn(total_timesteps=1)
    a0 = env.actions[0][0]
    # delta = r + gamma Q(3, a1) - Q(0, a0) = -1 + 0.9 - 1 = -1.1; Q(0, a0) = 1 + 0.5 * -1.1.
    expected = np.ones((4, 2))
    expected[0, a0] = 0.45
    assert agent.q_ == pytest.approx(expected)
    agent.learn(total_timesteps=1)
    a1 = env.actions[0][1]
    # Terminal: delta = 2 - Q(3, a1) = 1. Q(3, a1) = 1 + 0.5; the trace of (0, a0) is 0.9 * 0.8 = 0.72:
    # Q(0, a0) = 0.45 + 0.5 * 1 * 0.72 = 0.81.
    expected[0, a0] = 0.81
    expected[3, a1] = 1.5
    assert agent.q_ == pytest.approx(expected)
    assert agent.visited_.tolist() == [0, 3]
    (record,) = agent.history_
    assert {k: record[k] for k in ("steps", "return", "n_cells", "appends", "merges", "refused", "decisions")} == dict(
        steps=2, **{"return": 1.0}, n_cells=2, appends=2, merges=0, refused=0, decisions=2
    )


def _tile_agent(scripted, traces, same_action):
    """The scripted tile episode with the first seed whose two tie-breaks agree (or differ)."""
    for seed in range(50):
        env = scripted([TILE_EPISODE], dims=1)
        agent = TileSarsa(
            env,
            n_tilings=2,
            tiles_per_dim=2,
            iht_size=16,
            alpha=0.5,
            lam=0.8,
            gamma=0.9,
            epsilon=0.0,
            q_init=1.0,
            traces=traces,
            seed=seed,
        )
        agent.learn(total_timesteps=1)
        a0 = env.actions[0][0]
        agent.learn(total_timesteps=1)
        a1 = env.actions[0][1]
        if (a0 == a1) == same_action:
            return agent, a0, a1
    raise AssertionError("no seed in 0..49 gives this pair of tie-breaks")


@pytest.mark.parametrize(
    "traces,same_action,expected_a0,expected_a1",
    [
        # a1 == a0 (one column a): delta_2 = 2 - (0.225 + 0.5) = 1.275, alpha / n = 0.25, 0.25 * 1.275 = 0.31875.
        # Replacing: tile 0's trace is set back to 1: w0 = 0.225 + 0.31875, w1 = 0.225 + 0.31875 * 0.72.
        ("replacing", True, [0.54375, 0.4545, 0.81875], None),
        # Accumulating: tile 0's trace is 0.72 + 1 = 1.72: w0 = 0.225 + 0.31875 * 1.72 = 0.77325.
        ("accumulating", True, [0.77325, 0.4545, 0.81875], None),
        # a1 != a0: delta_2 = 2 - (0.5 + 0.5) = 1. Replacing clears tile 0's trace for a0 (it is active
        # again, for a1): w(0, a0) stays 0.225, w(1, a0) = 0.225 + 0.25 * 0.72 = 0.405.
        ("replacing", False, [0.225, 0.405, 0.5], [0.75, 0.5, 0.75]),
        # Accumulating keeps it: w(0, a0) = 0.225 + 0.25 * 0.72 = 0.405.
        ("accumulating", False, [0.405, 0.405, 0.5], [0.75, 0.5, 0.75]),
    ],
)
def test_tile_sarsa_update_by_hand(scripted, traces, same_action, expected_a0, expected_a1):
    # 1-D, [-10, 10], 2 tilings of 2 tiles (width 10); q = floor((x + 10) * 0.2), tiling t: (q + t) // 2.
    # x0 = -7: q = 0, tiles (0, 0) (1, 0) -> indices 0, 1. x1 = -3: q = 1, tiles (0, 0) (1, 1) -> 0, 2.
    # The terminal state is not coded. q_init 1 -> weights start at 0.5; alpha 0.5 -> 0.25 per tiling.
    # Step 1: delta = -1 + 0.9 * 1 - 1 = -1.1; w(0, a0) = w(1, a0) = 0.5 - 0.25 * 1.1 = 0.225; traces
    # decay by gamma lambda = 0.72.
    agent, a0, a1 = _tile_agent(scripted, traces, same_action)
    w = agent.weights_
    assert w.shape == (16, 2) and agent.n_cells == 3
    assert agent.tile_coder_.tiles().tolist() == [[0, 0], [1, 0], [1, 1]]
    expected = np.full((16, 2), 0.5)
    expected[:3, a0] = expected_a0
    if expected_a1 is not None:
        expected[:3, a1] = expected_a1
    assert w == pytest.approx(expected)
    (record,) = agent.history_
    assert (record["steps"], record["return"], record["n_cells"]) == (2, 1.0, 3)
    assert (record["appends"], record["refused"]) == (3, 0)
    assert record["decisions"] == 2 and record["merges"] == 0


class _Recorder(gym.Wrapper):
    """Keeps every observation the environment returns."""

    def __init__(self, env):
        super().__init__(env)
        self.seen = []

    def step(self, action):
        out = self.env.step(action)
        self.seen.append(out[0])
        return out


def test_tile_q_is_the_sum_of_the_active_weights():
    env = _Recorder(mountain_car())
    agent = TileSarsa(env, seed=0, epsilon=0.1).learn(total_episodes=3)
    x = np.array(env.seen[100:400:50])  # visited, so every tile is in the table
    active = [agent.tile_coder_(row, readonly=True) for row in x]
    assert all((a >= 0).all() for a in active)
    manual = np.array([agent.weights_[a].sum(axis=0) for a in active])
    assert agent.q_values(x) == pytest.approx(manual)
    # A state made of unseen tiles is worth q_init.
    assert agent.q_values(np.array([[5.0, 5.0]])).tolist() == [[0.0, 0.0, 0.0]]


def test_tile_overflows_are_counted_as_refused():
    agent = TileSarsa(mountain_car(), iht_size=16, seed=0).learn(total_episodes=2)
    h = agent.episode_history()
    assert agent.n_cells == 16 and h["refused"].sum() == agent.tile_coder_.overflows > 0
    assert h["appends"].sum() == 16


# -- the agent API ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["grid", "tiles"])
def test_same_seed_same_result_and_different_seed_differs(name):
    a = make_agent(name, mountain_car(), seed=7, epsilon=0.1).learn(total_episodes=8)
    b = make_agent(name, mountain_car(), seed=7, epsilon=0.1).learn(total_episodes=8)
    c = make_agent(name, mountain_car(), seed=8, epsilon=0.1).learn(total_episodes=8)
    for x, y in zip(learned_state(a), learned_state(b)):
        assert np.array_equal(x, y)
    assert a.episode_history()["return"].tolist() == b.episode_history()["return"].tolist()
    assert not np.array_equal(learned_state(a)[0], learned_state(c)[0])


@pytest.mark.parametrize("name", ["grid", "tiles"])
@pytest.mark.parametrize("unit", ["total_episodes", "total_timesteps"])
def test_learn_is_additive(name, unit):
    n = 4 if unit == "total_episodes" else 567
    whole = make_agent(name, mountain_car(), seed=3, epsilon=0.1).learn(**{unit: 2 * n + 1})
    parts = make_agent(name, mountain_car(), seed=3, epsilon=0.1)
    parts.learn(**{unit: n}).learn(**{unit: 1}).learn(**{unit: n})
    for x, y in zip(learned_state(whole), learned_state(parts)):
        assert np.array_equal(x, y)
    assert whole.num_timesteps == parts.num_timesteps and whole.num_episodes == parts.num_episodes
    assert whole.episode_history()["n_cells"].tolist() == parts.episode_history()["n_cells"].tolist()


@pytest.mark.parametrize("name", ["grid", "tiles"])
def test_episode_records(name):
    agent = make_agent(name, mountain_car(), seed=0).learn(total_episodes=4)
    h = agent.episode_history()
    assert set(h) >= {"episode", "steps", "return", "n_cells", "appends", "merges", "refused", "decisions", "wall_s"}
    assert h["episode"].tolist() == [1, 2, 3, 4]
    assert h["steps"].sum() == agent.num_timesteps and (h["decisions"] == h["steps"]).all()
    assert (h["return"] == -h["steps"]).all()  # MountainCar: -1 per step
    assert h["n_cells"][-1] == agent.n_cells == h["appends"].sum() and (h["merges"] == 0).all()
    if name == "grid":
        assert agent.n_cells == len(agent.visited_) == len(set(agent.visited_.tolist())) <= 100


@pytest.mark.parametrize("name", ["grid", "tiles"])
def test_predict_single_and_batch_and_queries_do_not_change_state(name):
    agent = make_agent(name, mountain_car(), seed=0, epsilon=0.1).learn(total_episodes=5)
    before = [x.copy() for x in learned_state(agent)]
    n_cells, rng_state = agent.n_cells, agent._rng.bit_generator.state
    obs = np.array([[-0.5, 0.0], [-1.1, -0.05], [0.3, 0.06], [5.0, 5.0]], dtype=np.float32)
    batch, none = agent.predict(obs)
    assert none is None and batch.shape == (4,) and batch.dtype == np.int64
    singles = [agent.predict(o)[0] for o in obs]
    assert batch.tolist() == singles and all(isinstance(a, int) for a in singles)
    if name == "grid":
        assert batch.tolist() == agent.q_[agent.cells(obs)].argmax(axis=1).tolist()
    else:
        assert batch.tolist() == agent.q_values(obs).argmax(axis=1).tolist()
    agent.predict(obs, deterministic=False)
    for x, y in zip(before, learned_state(agent)):
        assert np.array_equal(x, y)
    assert agent.n_cells == n_cells and agent._rng.bit_generator.state == rng_state
    with pytest.raises(ValueError, match="shape"):
        agent.predict(np.zeros(3))


@pytest.mark.parametrize("name", ["grid", "tiles"])
def test_predict_before_learn_is_a_clear_error(name):
    with pytest.raises(RuntimeError, match="learn"):
        make_agent(name, mountain_car()).predict(np.zeros(2))


@pytest.mark.parametrize("name,extra", [("grid", dict(bins=[6, 4, 5, 3])), ("tiles", dict(iht_size=512))])
def test_save_load_round_trip_is_exact(tmp_path, name, extra):
    env = gym.make("CartPole-v1")
    agent = make_agent(name, env, seed=1, obs_bounds=CARTPOLE_BOUNDS, epsilon=0.1, **extra).learn(total_episodes=30)
    if name == "tiles":
        assert agent.tile_coder_.overflows > 0  # the hashed part is saved too
    path = agent.save(tmp_path / "model")
    loaded = avq.load(path, env=gym.make("CartPole-v1"))
    assert type(loaded) is type(agent) and loaded.get_params() == agent.get_params()
    for x, y in zip(learned_state(agent), learned_state(loaded)):
        assert np.array_equal(x, y)
    assert loaded.n_cells == agent.n_cells and loaded.num_timesteps == agent.num_timesteps
    if name == "tiles":
        assert loaded.tile_coder_.overflows == agent.tile_coder_.overflows
    obs = np.random.default_rng(0).uniform(-1, 1, size=(200, 4)) * [2.4, 2, 0.2, 2]
    assert np.array_equal(agent.predict(obs)[0], loaded.predict(obs)[0])
    assert type(agent).load(path).num_episodes == 30  # env made from the stored id
    loaded.learn(total_episodes=2)  # and it can go on learning


# -- Sutton & Barto's Mountain Car --------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [0, 1])
def test_tile_sarsa_solves_mountain_car_like_the_book(seed):
    # Sutton & Barto (2018), Fig. 12.10: replacing-trace Sarsa(lambda), 8 tilings, epsilon 0, q_init 0,
    # episodes not capped: about 180-300 steps per episode over the first 50 episodes, by alpha and lambda.
    env = mountain_car(max_episode_steps=5000)
    agent = TileSarsa(env, n_tilings=8, tiles_per_dim=8, alpha=0.5, lam=0.9, epsilon=0.0, q_init=0.0, seed=seed)
    agent.learn(total_episodes=50)
    steps = agent.episode_history()["steps"]
    assert 150 <= steps.mean() <= 350
    assert steps[-10:].mean() < steps[:10].mean()


@pytest.mark.parametrize(
    "make",
    [
        lambda env: avq.TabularSarsa(env, alpha=0.5, epsilon=0.0, seed=0),
        lambda env: avq.GridSarsa(env, bins=20, alpha=0.5, epsilon=0.0, seed=0),
    ],
    ids=["tabular", "grid"],
)
def test_table_agents_make_a_row_for_the_terminal_observation_and_never_learn_from_it(make):
    # Start (0, 0), one step to (1, 0) with r -1, then the terminal step to (9, 0) with r +10.
    # Both agents run the same step (avq.agents._td.table_step): every observation reached gets a row,
    # the terminal one included, so n_cells = 3; the terminal row keeps q_init = 0 (nothing bootstraps
    # from it). alpha 0.5, lambda 0.7, gamma 1, replacing traces, epsilon 0 (ties go to a random action):
    #   step 1: delta = -1 + 0 - 0 = -1 -> Q[s0, a0] = -0.5, E[s0, a0] = 0.7
    #   step 2: delta = 10 - 0 = 10 -> Q[s1, a1] = 5, Q[s0, a0] = -0.5 + 0.5 * 10 * 0.7 = 3.0
    from conftest import ScriptedEnv

    env = ScriptedEnv([((0.0, 0.0), [((1.0, 0.0), -1, False, False, False), ((9.0, 0.0), 10, True, False, False)])])
    agent = make(env)
    agent.learn(total_episodes=1)
    assert agent.n_cells == 3 and agent.history_[0]["appends"] == 3
    a0, a1 = env.actions[0]
    cells = (
        np.arange(3)
        if isinstance(agent, avq.TabularSarsa)
        else agent.cells(np.array([[0.0, 0.0], [1.0, 0.0], [9.0, 0.0]]))
    )
    q = agent.q_[cells]
    assert q[0, a0] == pytest.approx(3.0) and q[1, a1] == 5.0
    assert q[2].tolist() == [0.0, 0.0]
