"""``ignore_noise``: a dimension that the observation before does not predict is noise, and the agents' metric
(``avq``'s planning agent and ``avq-sarsa``) gives it an infinite scale once ``scale_warmup`` observations are
counted; the test itself (avq.agents._noise) on observations made by hand; saved and resumed exactly."""

import gymnasium as gym
import numpy as np
import pytest

import avq
from avq import AVQSarsa, PlanningAVQ, make_agent
from avq.agents._noise import NOISE_R2, RELEVANT_R2, matters, noise_dims
from avq.agents._warmup import RunningSpread, load_scale_state
from avq.agents.plan.memory import COMPOSED, HELD
from avq.agents.plan.state import MEM_N
from avq.envs import IrrelevantDims


def walk_and_noise(t, seed=0):
    """``t`` observations in one episode: dimension 0 a smooth drift, 1 drawn afresh each step, 2 constant."""
    rng = np.random.default_rng(seed)
    obs = np.column_stack([np.cumsum(rng.uniform(-0.01, 0.01, t)), rng.uniform(0, 1, t), np.full(t, 0.3)])
    follows = np.ones(t, dtype=bool)
    follows[0] = False
    return obs, follows


def test_a_dimension_drawn_afresh_each_step_is_noise_and_a_drifting_or_constant_one_is_not():
    obs, follows = walk_and_noise(500)
    assert noise_dims(obs, follows).tolist() == [False, True, False]


def test_a_dimension_the_previous_observation_predicts_through_another_is_not_noise():
    # x1[t + 1] = x0[t]: not its own past but another dimension's, which a linear prediction sees.
    rng = np.random.default_rng(1)
    x0 = rng.uniform(0, 1, 400)
    obs = np.column_stack([x0, np.r_[0.0, x0[:-1]]])
    assert noise_dims(obs, np.r_[False, np.ones(399, dtype=bool)]).tolist() == [True, False]


def test_explained_share_is_compared_with_the_threshold():
    # x[t + 1] = c * x[t] + e: the share explained is c^2 Var(x) / Var(x) = c^2 for a stationary AR(1).
    rng = np.random.default_rng(2)
    for c, noise in ((0.2, True), (0.45, False)):  # 0.04 and 0.2 against NOISE_R2 0.1
        x = np.zeros(20_000)
        for t in range(1, len(x)):
            x[t] = c * x[t - 1] + rng.normal()
        assert NOISE_R2 == 0.1
        assert noise_dims(x[:, None], np.r_[False, np.ones(len(x) - 1, dtype=bool)]).tolist() == [noise]


def test_only_pairs_within_an_episode_count():
    # 40 steps of a slow drift, then 400 episodes of one observation each drawn afresh: within episodes the
    # dimension is predictable; counted across the resets it would look like noise.
    rng = np.random.default_rng(3)
    obs = np.r_[np.linspace(0, 1, 40), rng.uniform(0, 1, 400)][:, None]
    follows = np.r_[False, np.ones(39, dtype=bool), np.zeros(400, dtype=bool)]
    assert noise_dims(obs, follows).tolist() == [False]
    assert noise_dims(obs, np.r_[False, np.ones(439, dtype=bool)]).tolist() == [True]


def test_too_few_pairs_find_nothing():
    obs, follows = walk_and_noise(8)  # 7 pairs < 2 * (3 + 1)
    assert not noise_dims(obs, follows).any()
    obs, follows = walk_and_noise(500)
    follows[8:] = False  # the same observations, 7 pairs among them
    assert not noise_dims(obs, follows).any()


def test_the_log_keeps_the_first_observations_and_whether_each_follows_the_one_before():
    log = RunningSpread(2, 3, log=True)
    assert log.add(np.array([1.0, 2.0]), start=True) and log.add(np.array([3.0, 4.0]))
    assert not log.add(np.array([5.0, 6.0]), start=True)  # full now
    assert not log.add(np.array([7.0, 8.0])) and log.count == 3 and log.full
    assert log.obs.tolist() == [[1, 2], [3, 4], [5, 6]] and log.follows.tolist() == [False, True, False]
    assert log.actions.tolist() == [-1, -1, -1] and log.rewards.tolist() == [0, 0, 0]
    log = RunningSpread(1, 2, log=True)
    log.add(np.array([1.0]), start=True)
    log.add(np.array([2.0]), False, 3, -1.5)  # (the action taken in [1.0] and the reward that came with [2.0])
    assert log.actions.tolist() == [-1, 3] and log.rewards.tolist() == [0.0, -1.5]


def drawn_afresh(t=1000, seed=0):
    """``t`` steps of one episode: dimension 0 a drift, 1 and 2 drawn afresh at every step, actions 0 or 1 at random;
    the reward is +1 where the action is 1 exactly when dimension 1 is above 0.5 (a context), else -1; dimension 2
    is appended noise. ``actions[s]`` and ``rewards[s]`` are those of the step into ``obs[s]``."""
    rng = np.random.default_rng(seed)
    obs = np.column_stack([np.cumsum(rng.uniform(-0.01, 0.01, t)), rng.uniform(0, 1, (t, 2))])
    actions = np.r_[-1, rng.integers(0, 2, t - 1)]
    rewards = np.r_[0.0, np.where(actions[1:] == (obs[:-1, 1] > 0.5), 1.0, -1.0)]
    return obs, np.r_[False, np.ones(t - 1, dtype=bool)], actions, rewards


def test_a_dimension_drawn_afresh_that_sets_the_reward_is_kept_and_noise_beside_it_is_not():
    obs, follows, actions, rewards = drawn_afresh()
    assert noise_dims(obs, follows).tolist() == [False, True, True]  # (unpredictable, both)
    assert noise_dims(obs, follows, actions, rewards).tolist() == [False, False, True]
    after = np.flatnonzero(follows)
    kept = matters(obs, after, actions[after], rewards[after], np.array([False, True, True]))
    assert kept.tolist() == [False, True, False]
    # The same rewards drawn at random: nothing to explain, so dimension 1 is noise again.
    shuffled = np.random.default_rng(1).permutation(rewards)
    assert noise_dims(obs, follows, actions, shuffled).tolist() == [False, True, True]


def test_a_dimension_whose_value_after_the_step_sets_the_reward_is_kept():
    # A coin drawn afresh at every step (dimension 1) pays +1 when it lands on 1: the reward comes with the
    # observation the step led to, so the coin's previous value explains none of it and its new value all.
    rng = np.random.default_rng(0)
    t = 1000
    coin = rng.integers(0, 2, t).astype(float)
    obs = np.column_stack([np.cumsum(rng.uniform(-0.01, 0.01, t)), coin])
    follows, actions = np.r_[False, np.ones(t - 1, dtype=bool)], np.r_[-1, rng.integers(0, 2, t - 1)]
    assert noise_dims(obs, follows).tolist() == [False, True]
    assert noise_dims(obs, follows, actions, np.r_[0.0, coin[1:]]).tolist() == [False, False]
    assert noise_dims(obs, follows, actions, rng.permutation(np.r_[0.0, coin[1:]])).tolist() == [False, True]


def test_a_dimension_drawn_afresh_that_moves_the_next_state_is_kept():
    # A gust drawn afresh each step (dimension 1) pushes the position (dimension 0) along with the action; the
    # rewards are constant, so only the next position tells. Moved by a tenth of its own spread, it explains far
    # more than RELEVANT_R2 of the move's variance that the action leaves.
    rng = np.random.default_rng(0)
    t = 1000
    gust, actions = rng.uniform(-1, 1, t), np.r_[-1, rng.integers(0, 2, t - 1)]
    pos = np.zeros(t)
    for s in range(1, t):
        pos[s] = pos[s - 1] + 0.1 * (2 * actions[s] - 1) + 0.1 * gust[s - 1] + rng.normal(0, 0.02)
    obs, follows = np.column_stack([pos, gust]), np.r_[False, np.ones(t - 1, dtype=bool)]
    assert noise_dims(obs, follows).tolist() == [False, True]
    assert noise_dims(obs, follows, actions, np.zeros(t)).tolist() == [False, False]
    after = np.flatnonzero(follows)
    move_left = np.var(pos[after] - pos[after - 1] - 0.1 * (2 * actions[after] - 1))
    assert 0.1**2 * np.var(gust) / move_left > 10 * RELEVANT_R2


class Context(gym.Env):
    """100 steps an episode; the observation is a context drawn afresh at every step and the time; the action
    equal to (context > 0.5) pays +1, the other -1."""

    observation_space = gym.spaces.Box(0.0, 1.0, (2,), np.float32)
    action_space = gym.spaces.Discrete(2)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.t = 0
        return self._obs(), {}

    def _obs(self):
        self.c = self.np_random.uniform()
        return np.array([self.c, self.t / 100], np.float32)

    def step(self, action):
        r = 1.0 if int(action) == int(self.c > 0.5) else -1.0
        self.t += 1
        return self._obs(), r, False, self.t >= 100, {}


@pytest.mark.parametrize("cls", [PlanningAVQ, AVQSarsa])
def test_the_agents_keep_a_context_drawn_afresh_that_sets_the_reward(tmp_path, cls):
    agent = cls(Context(), seed=0, scale_warmup=300).learn(total_timesteps=1_000)
    assert np.isfinite(agent.scale_).all()  # (the test was made: 1,000 steps > 300)
    assert np.isinf(cls(IrrelevantDims(Context(), 1), seed=0, scale_warmup=300).learn(total_timesteps=1_000).scale_[2])
    # Saved during the warm-up, the log keeps the steps' actions and rewards.
    part = cls(Context(), seed=0, scale_warmup=300).learn(total_timesteps=200)
    loaded = avq.load(part.save(tmp_path / "m.zip"), env=Context())
    steps = loaded._spread.follows[:200]  # (the steps within an episode: 99 of each 100 observations)
    assert steps.sum() == 198 and (loaded._spread.actions[:200][steps] >= 0).all()
    assert (np.abs(loaded._spread.rewards[:200][steps]) == 1.0).all()
    assert np.array_equal(loaded._spread.actions, part._spread.actions)
    assert np.array_equal(loaded._spread.rewards, part._spread.rewards)


def test_planning_avq_learns_a_context_drawn_afresh():
    agent = PlanningAVQ(Context(), seed=0).learn(total_timesteps=20_000)
    assert np.isfinite(agent.scale_).all() and agent.episode_history()["return"][-20:].mean() > 50
    blind = PlanningAVQ(Context(), seed=0, scale=[1e9, 1.0]).learn(total_timesteps=20_000)  # (the context left out)
    assert abs(blind.episode_history()["return"][-20:].mean()) < 20


def test_an_old_noise_log_without_actions_and_rewards_loads():
    spread = RunningSpread(1, 3, log=True)
    log = np.array([[1.0, 0.0], [2.0, 1.0]])  # (observation, follows): as saved before actions and rewards
    load_scale_state({"scale_count": 2}, {"noise_log": log}, np.ones(1), np.ones(1, dtype=bool), spread)
    assert spread.obs[:2].ravel().tolist() == [1.0, 2.0] and spread.follows[:2].tolist() == [False, True]
    assert spread.actions[:2].tolist() == [-1, -1] and spread.rewards[:2].tolist() == [0.0, 0.0]
    with pytest.raises(ValueError, match=r"array noise_log has shape \(2, 3\); expected \(2, 4\)"):
        load_scale_state(
            {"scale_count": 2}, {"noise_log": np.zeros((2, 3))}, np.ones(1), np.ones(1, dtype=bool), spread
        )


def mountain_car(k, kind="noise"):
    return IrrelevantDims(gym.make("MountainCar-v0"), k, kind=kind)


@pytest.mark.parametrize("cls", [PlanningAVQ, AVQSarsa])
def test_the_agents_ignore_noise_dimensions_once_the_warmup_is_counted(cls):
    agent = cls(mountain_car(2), seed=0, scale_warmup=300).learn(total_timesteps=250)
    assert np.isfinite(agent.scale_).all()  # (not yet: 250 of 300 observations)
    agent.learn(total_timesteps=400)  # (the test is made at the end of an episode)
    assert agent.scale_[:2].tolist() == pytest.approx([1.8, 0.14]) and np.isinf(agent.scale_[2:]).all()
    # The cells no longer depend on the noise dimensions.
    rng = np.random.default_rng(0)
    obs = np.column_stack([rng.uniform(-1.2, 0.6, 200), rng.uniform(-0.07, 0.07, 200), rng.uniform(0, 1, (200, 2))])
    moved = obs.copy()
    moved[:, 2:] = rng.uniform(0, 1, (200, 2))
    assert agent.cells(obs).tolist() == agent.cells(moved).tolist()
    assert agent.predict(obs)[0].tolist() == agent.predict(moved)[0].tolist()


def test_once_the_noise_is_left_out_a_decision_that_ended_only_because_of_it_goes_on():
    # While the noise counts in the metric, decisions end at nearly every step: the nearest vector jumps with it.
    # Left out, many such transitions start and end in one cell, where the decision would have gone on. The
    # agent (no merging) with compose_crossings remembers every transition that ended only because the cell
    # changed as a crossing, and the model records those whose two ends now lie in one cell as going on (CONT),
    # not as a decision that ended in its own cell.
    agent = PlanningAVQ(mountain_car(2), seed=0, scale_warmup=300, compose_crossings=True)
    assert agent.rho is None

    def crossings():
        rows = remembered(agent)
        # MountainCar has no collisions and ends no episode this early: every transition is a crossing.
        assert (rows[:, 3] == COMPOSED).all()
        return going_on(agent, rows[:, 3] == COMPOSED)

    agent.learn(total_timesteps=250)  # (the noise not yet found)
    before = crossings()
    agent.learn(total_timesteps=400)
    assert np.isinf(agent.scale_[2:]).all()
    after = crossings()
    assert before <= 2 and after > 100
    # Without it, no transition is a crossing and none goes on.
    plain = PlanningAVQ(mountain_car(2), seed=0, scale_warmup=300, compose_crossings=False).learn(total_timesteps=650)
    assert np.isinf(plain.scale_[2:]).all()
    assert not plain._ag.mem_i[: int(plain._ag.S[MEM_N]), 3].any() and plain._model.a.cint.sum() == 0


def remembered(agent):
    """The agent's remembered transitions: rows (action, start cell, end cell (-1: the end), crossing flag)."""
    return agent._ag.mem_i[: int(agent._ag.S[MEM_N])]


def going_on(agent, composed):
    """How many of the remembered transitions (``composed``: those that may go on) start and end in one cell,
    checked against the model: it counts as going on exactly those, pair by pair."""
    rows, m = remembered(agent), agent._model.a  # (taken again: growth reallocates them)
    goes_on = composed & (rows[:, 1] == rows[:, 2]) & (rows[:, 2] >= 0)
    for i, a in {(int(r[1]), int(r[0])) for r in rows}:
        assert m.cint[i, a] == (goes_on & (rows[:, 1] == i) & (rows[:, 0] == a)).sum()
    return goes_on.sum()


def test_by_default_the_crossings_remembered_go_on_once_the_noise_test_leaves_dimensions_out():
    # "noise": every crossing is remembered, held (it ends in its own cell as without the option) until the noise
    # test leaves dimensions out; then those in memory go on where their two ends lie in one cell. Later
    # crossings are held again: a cut later does not make them go on.
    agent = PlanningAVQ(mountain_car(2), seed=0, scale_warmup=300)  # (the default)
    assert agent.compose_crossings == "noise"
    agent.learn(total_timesteps=250)
    rows = remembered(agent)
    assert len(rows) > 100 and (rows[:, 3] == HELD).all()
    assert going_on(agent, rows[:, 3] == COMPOSED) == 0 and agent._model.a.cint.sum() == 0
    agent.learn(total_timesteps=400)
    assert np.isinf(agent.scale_[2:]).all()
    rows = remembered(agent)
    composed = rows[:, 3] == COMPOSED
    k = int(composed.sum())  # the transitions remembered when the noise was found, in the order they were made
    assert k >= 100 and composed[:k].all() and (rows[k:, 3] == HELD).all() and len(rows) > k
    assert going_on(agent, composed) > 100


def test_a_bad_compose_crossings_gets_a_clear_error():
    with pytest.raises(ValueError, match="compose_crossings must be True, False or 'noise'"):
        PlanningAVQ("MountainCar-v0", compose_crossings=1)
    with pytest.raises(ValueError, match="compose_crossings must be True, False or 'noise'"):
        PlanningAVQ("MountainCar-v0", compose_crossings="always")


@pytest.mark.parametrize(
    "params, env",
    [
        (dict(ignore_noise=False), mountain_car(2)),  # off
        (dict(scale=None), mountain_car(2)),  # a metric the user gave
        (dict(scale=None), mountain_car(2, kind="walk")),
    ],
)
def test_nothing_is_ignored_when_the_test_is_off_or_finds_nothing(params, env):
    agent = PlanningAVQ(env, seed=0, scale_warmup=300, **params).learn(total_timesteps=1000)
    assert np.isfinite(agent.scale_).all()


def test_on_the_task_itself_the_run_is_the_same_with_and_without_the_test():
    runs = [
        make_agent("avq", "CartPole-v1", seed=3, scale_warmup=200, ignore_noise=on).learn(total_episodes=30)
        for on in (True, False)
    ]
    assert np.isfinite(runs[0].scale_).all()
    assert np.array_equal(runs[0].codebook_, runs[1].codebook_) and np.array_equal(runs[0].q_, runs[1].q_)


@pytest.mark.parametrize("name", ["avq", "avq-sarsa"])
@pytest.mark.parametrize("first", [2, 8])  # saved during the warm-up (1,000 observations, 200 an episode), and after
def test_the_test_is_saved_and_resumed_exactly(tmp_path, name, first):
    whole = make_agent(name, mountain_car(2), seed=1).learn(total_episodes=15)
    part = make_agent(name, mountain_car(2), seed=1).learn(total_episodes=first)
    loaded = avq.load(part.save(tmp_path / "m.zip"), env=part.env)
    assert np.array_equal(loaded.scale_, part.scale_) and np.isinf(part.scale_[2:]).all() == (first == 8)
    loaded.learn(total_episodes=15 - first)
    assert np.isinf(whole.scale_[2:]).all() and np.array_equal(loaded.scale_, whole.scale_)
    assert np.array_equal(loaded.codebook_, whole.codebook_) and np.array_equal(loaded.q_, whole.q_)
    assert loaded.episode_history()["return"].tolist() == whole.episode_history()["return"].tolist()


@pytest.mark.parametrize("cls", [PlanningAVQ, AVQSarsa])
def test_a_bad_ignore_noise_gets_a_clear_error(cls):
    with pytest.raises(ValueError, match="ignore_noise must be True or False"):
        cls("MountainCar-v0", ignore_noise="yes")
