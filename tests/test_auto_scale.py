"""``scale="auto"``: the metric's scale of the dimensions without finite bounds, estimated from the first
observations (``AVQSarsa``: ``avq-sarsa``; the planning agent, ``avq``'s class on tasks without collisions, in
test_plan_general.py), saved and resumed exactly; explicit bounds win."""

import gymnasium as gym
import numpy as np
import pytest

import avq
from avq import AVQSarsa, make_agent
from avq.agents.avq_sarsa import episode_end, kernels as core

INF = np.inf
#: The bounds the README once gave CartPole-v1 for ``avq``.
CARTPOLE_BOUNDS = [[-2.4, 2.4], [-3.0, 3.0], [-0.21, 0.21], [-3.5, 3.5]]


class Recorder(gym.Wrapper):
    """Keeps every observation the agent is given (resets included), in order."""

    def __init__(self, env):
        super().__init__(env)
        self.seen = []

    def reset(self, *, seed=None, options=None):
        obs, info = self.env.reset(seed=seed, options=options)
        self.seen.append(np.asarray(obs, dtype=np.float64))
        return obs, info

    def step(self, action):
        out = self.env.step(action)
        self.seen.append(np.asarray(out[0], dtype=np.float64))
        return out


def half_bounded(scripted, episodes):
    """A scripted task whose dimension 0 lies in [-1, 1] and dimension 1 is unbounded."""
    return scripted(episodes, low=np.array([-1.0, -INF]), high=np.array([1.0, INF]))


def step(x, y, end=False):
    return (x, y), 0.0, end, False, False


def test_the_scale_is_four_standard_deviations_of_the_first_observations(scripted):
    # Dimension 1 takes the values below; the scale is 1 until the first episode ends, then 4 std of the
    # observations so far, until scale_warmup (5) are counted; after that it stays.
    env = half_bounded(
        scripted,
        [
            ((0.0, 0.0), [step(0.5, 2.0), step(0.0, -1.0, end=True)]),
            ((0.0, 3.0), [step(0.0, 7.0), step(0.0, 100.0, end=True)]),
        ],
    )
    agent = AVQSarsa(env, scale_warmup=5, value_trigger=None, merge_every=0, seed=0)
    assert agent.scale_.tolist() == [2.0, 1.0]
    agent.learn(total_timesteps=1)
    assert agent.scale_.tolist() == [2.0, 1.0]  # within the first episode
    agent.learn(total_timesteps=1)
    assert agent.scale_[0] == 2.0 and agent.scale_[1] == pytest.approx(4 * np.std([0.0, 2.0, -1.0]), rel=1e-12)
    agent.learn(total_episodes=1)  # counts 3.0 and 7.0, not 100.0 (the sixth observation)
    first = 4 * np.std([0.0, 2.0, -1.0, 3.0, 7.0])
    assert agent.scale_[1] == pytest.approx(first, rel=1e-12)
    agent.learn(total_episodes=4)
    assert agent.scale_[1] == pytest.approx(first, rel=1e-12)
    assert np.array_equal(agent._inv_scale, 1.0 / agent.scale_)
    # The queries use it: in units of (2, first = 11.5), (0.5, 0) is 0.25 from (0, 0) and 0.17 from (0.5, 2).
    agent._V[:2] = [[0.0, 0.0], [0.5, 2.0]]
    agent._S[core.SIZE] = 2
    assert agent.cells(np.array([[0.5, 0.0], [0.0, 0.0]])).tolist() == [1, 0]
    assert agent.predict(np.array([0.5, 0.0]))[0] == agent.q_[1].argmax()


def test_a_dimension_that_has_not_varied_keeps_scale_one(scripted):
    env = half_bounded(scripted, [((0.0, 4.0), [step(0.5, 4.0), step(-0.5, 4.0, end=True)])])
    agent = AVQSarsa(env, value_trigger=None, seed=0).learn(total_episodes=3)
    assert agent.scale_.tolist() == [2.0, 1.0]


def test_a_new_scale_makes_the_merge_pass_find_its_pairs_again(scripted):
    # Three cells A (0, 0), B (0.5, 0), C (0, 1); A and C have the same values, B others. In units of
    # (2, 1), A and B are each other's nearest: no merge, and the merge pass keeps that pair. Episode 2's
    # observations (y = -10, 10) make the scale of y 4 * std(0, 0, -10, 10) = 28.3: now A and C are each
    # other's nearest, and merge into their midpoint, which the pair kept from before would not have allowed.
    env = half_bounded(
        scripted, [((0.0, 0.0), [step(0.0, 0.0, end=True)]), ((0.0, -10.0), [step(0.0, 10.0, end=True)])]
    )
    agent = AVQSarsa(env, value_trigger=None, rho=0.01, merge_every=1, merge_age=0, q_init=0.0, seed=0)
    agent.learn(total_episodes=1)
    assert agent.scale_.tolist() == [2.0, 1.0]
    agent._V[:3] = [[0.0, 0.0], [0.5, 0.0], [0.0, 1.0]]
    agent._Q[:3] = [[0.0, 0.0], [5.0, 5.0], [0.0, 0.0]]
    agent._born[:3] = 0
    agent._S[core.SIZE] = 3
    agent._S[core.GEOM] += 1
    assert episode_end.merge_pass(*agent._state()[:10]) == 0  # pairs: A-B only
    agent.learn(total_episodes=1)
    assert agent.scale_[1] == pytest.approx(4 * np.std([0.0, 0.0, -10.0, 10.0]), rel=1e-12)
    assert agent.history_[-1]["merges"] == 1
    assert agent.codebook_.tolist() == [[0.0, 0.5], [0.5, 0.0]]


def test_avq_learns_cartpole_without_obs_bounds():
    env = Recorder(gym.make("CartPole-v1"))
    agent = make_agent("avq", env, seed=0).learn(total_episodes=20)
    assert agent.get_params()["obs_bounds"] is None and agent.get_params()["scale"] == "auto"
    space = env.observation_space
    factor = np.array(agent.get_params()["scale_factor"])  # (CartPole-v1's entry: the pole's dimensions at 0.5)
    assert factor.tolist() == [1.0, 1.0, 0.5, 0.5]
    bounded = [0, 2]  # the position and the angle have finite bounds; the velocities do not
    assert np.array_equal(
        agent.scale_[bounded], ((space.high.astype(float) - space.low.astype(float)) * factor)[bounded]
    )
    seen = np.array(env.seen)
    assert len(seen) < 1000  # all within the warm-up (scale_warmup 1000)
    assert agent.scale_[[1, 3]] == pytest.approx(4 * seen[:, [1, 3]].std(axis=0) * factor[[1, 3]], rel=1e-12)
    assert agent.n_cells >= 1 and len(agent.history_) == 20


@pytest.mark.parametrize("first", [3, 15])  # saved during the warm-up (100 observations), and after it
def test_the_estimate_is_saved_and_resumed_exactly(tmp_path, first):
    whole = make_agent("avq-sarsa", "CartPole-v1", seed=1, scale_warmup=100).learn(total_episodes=25)
    part = make_agent("avq-sarsa", "CartPole-v1", seed=1, scale_warmup=100).learn(total_episodes=first)
    assert (part._spread.count < 100) == (first == 3)
    loaded = avq.load(part.save(tmp_path / "m.zip"))
    assert np.array_equal(loaded.scale_, part.scale_)
    loaded.learn(total_episodes=25 - first)
    assert np.array_equal(loaded.scale_, whole.scale_)
    assert np.array_equal(loaded.codebook_, whole.codebook_) and np.array_equal(loaded.q_, whole.q_)
    assert loaded.episode_history()["return"].tolist() == whole.episode_history()["return"].tolist()


def test_given_bounds_win_over_the_estimate():
    agent = make_agent("avq-sarsa", "CartPole-v1", seed=0, obs_bounds=CARTPOLE_BOUNDS).learn(total_episodes=5)
    assert agent.scale_.tolist() == [4.8, 6.0, 0.42, 7.0]
    partly = make_agent("avq-sarsa", "CartPole-v1", seed=0, obs_bounds=[None, [-3, 3], None, None]).learn(
        total_episodes=5
    )
    assert partly.scale_[1] == 6.0 and partly.scale_[3] not in (1.0, 7.0)


def test_a_model_file_with_a_scale_that_does_not_fit_is_refused(tmp_path):
    agent = make_agent("avq-sarsa", "CartPole-v1", seed=0).learn(total_episodes=2)
    meta, arrays = agent._state_dict()
    arrays["scale"] = arrays["scale"] * np.array([2.0, 1.0, 1.0, 1.0])  # a bounded dimension's scale changed
    fresh = make_agent("avq-sarsa", "CartPole-v1", seed=0)
    fresh._setup()
    with pytest.raises(ValueError, match="array scale .* does not fit the parameters' scale"):
        fresh._load_state_dict(meta, arrays)


@pytest.mark.parametrize("name", ["avq-paper", "avq-maze"])
def test_the_papers_scale_stays_one(name):
    agent = make_agent(name, "CartPole-v1", seed=0).learn(total_episodes=3)
    assert agent.scale_.tolist() == [1.0, 1.0, 1.0, 1.0]


def test_spread_estimates_every_dimension_but_those_obs_bounds_bounds(scripted):
    # scale="spread": dimension 0 is bounded by the space ([-1, 1]) and still estimated; the space's range is only
    # the start (and dimension 1, unbounded, starts at 1), until the first episode ends.
    env = half_bounded(scripted, [((0.0, 0.0), [step(0.5, 2.0), step(0.0, -1.0, end=True)])])
    agent = AVQSarsa(env, scale="spread", scale_warmup=3, value_trigger=None, merge_every=0, seed=0)
    assert agent.scale_.tolist() == [2.0, 1.0]
    agent.learn(total_episodes=1)
    assert agent.scale_ == pytest.approx([4 * np.std([0.0, 0.5, 0.0]), 4 * np.std([0.0, 2.0, -1.0])], rel=1e-12)
    # obs_bounds wins for the dimension it bounds; the others are estimated.
    given = AVQSarsa(
        env, scale="spread", obs_bounds=[[-3.0, 3.0], None], scale_warmup=3, value_trigger=None, merge_every=0, seed=0
    ).learn(total_episodes=1)
    assert given.scale_[0] == 6.0 and given.scale_[1] == pytest.approx(4 * np.std([0.0, 2.0, -1.0]), rel=1e-12)
    with pytest.raises(ValueError, match="scale must be 'auto', 'spread', None"):
        AVQSarsa(env, scale="wide")


@pytest.mark.parametrize("cls", [AVQSarsa, avq.PlanningAVQ])
def test_scale_factor_multiplies_the_scale_whatever_its_source(scripted, cls, tmp_path):
    # Dimension 0: the bounds' range 2 (scale "auto") times 3; dimension 1: 4 std of the first observations
    # times 0.5, from the start (1 * 0.5) and after the estimate; a resumed agent keeps both.
    env = half_bounded(scripted, [((0.0, 0.0), [step(0.5, 2.0), step(0.0, -1.0, end=True)])])
    kw = dict(scale_warmup=3, scale_factor=[3.0, 0.5], seed=0)
    agent = cls(env, **kw)
    assert agent.scale_.tolist() == [6.0, 0.5]
    agent.learn(total_episodes=1)
    assert agent.scale_ == pytest.approx([6.0, 0.5 * 4 * np.std([0.0, 2.0, -1.0])], rel=1e-12)
    plain = cls(env, scale_warmup=3, seed=0).learn(total_episodes=1)
    assert agent.scale_ / plain.scale_ == pytest.approx([3.0, 0.5], rel=1e-12)
    # A number applies to every dimension, and to a scale given outright.
    assert cls(env, scale=[1.0, 4.0], scale_factor=2, seed=0).scale_.tolist() == [2.0, 8.0]
    assert agent.get_params()["scale_factor"] == [3.0, 0.5]
    loaded = avq.load(agent.save(tmp_path / "m.zip"), env=env)
    assert loaded.get_params()["scale_factor"] == [3.0, 0.5] and np.array_equal(loaded.scale_, agent.scale_)


@pytest.mark.parametrize(
    "bad, what",
    [
        ([1.0, 2.0, 3.0], "a number or 2 numbers"),
        ([1.0, 0.0], "dimension 1 has 0.0"),
        (np.inf, "dimension 0 has inf"),
        ("wide", "a number or 2 numbers"),
    ],
)
def test_a_bad_scale_factor_gets_a_clear_error(scripted, bad, what):
    env = half_bounded(scripted, [((0.0, 0.0), [step(0.5, 2.0, end=True)])])
    for cls in (AVQSarsa, avq.PlanningAVQ):
        with pytest.raises(ValueError, match=f"scale_factor must be .*{what}"):
            cls(env, scale_factor=bad)
