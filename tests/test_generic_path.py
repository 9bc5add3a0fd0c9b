"""The generic path's one compiled call per step gives the same results whatever types the env returns."""

import gymnasium as gym
import numpy as np
import pytest

import avq
from avq.envs import GridMaze


class MixedTypes(gym.Wrapper):
    """The same maze, with observations of changing dtype and layout and rewards of changing type."""

    def __init__(self, env):
        super().__init__(env)
        self.k = 0

    def step(self, action):
        obs, r, terminated, truncated, info = self.env.step(action)
        self.k += 1
        kind = self.k % 5
        if kind == 1:
            obs = obs.astype(np.float64)
        elif kind == 2:
            obs = np.repeat(obs, 2)[::2]  # a strided view: not C-contiguous
        elif kind == 3:
            obs = [float(v) for v in obs]
        elif kind == 4:
            r = int(r)
            terminated, truncated = np.bool_(terminated), np.bool_(truncated)
        return obs, r, terminated, truncated, info


@pytest.mark.parametrize("name", ["avq-paper", "avq"])
def test_observation_and_reward_types_do_not_change_what_is_learned(name):
    runs = []
    for wrap in (False, True):
        env = gym.make("avq/GridMaze-v0")
        env = MixedTypes(env) if wrap else env
        agent = avq.make_agent(name, env, seed=2, fused=False)
        assert agent._fused_runner() is None
        runs.append(agent.learn(total_episodes=60).learn(total_timesteps=77))
    a, b = runs
    assert np.array_equal(a.codebook_, b.codebook_) and np.array_equal(a.q_, b.q_)
    for key in ("steps", "return", "n_cells", "appends", "merges"):
        assert np.array_equal(a.episode_history()[key], b.episode_history()[key])


def test_an_observation_of_the_wrong_shape_midway_is_refused_naming_the_step():
    class Bad(gym.Wrapper):
        def step(self, action):
            obs, r, te, tr, info = self.env.step(action)
            return (np.zeros(3, np.float32) if self.env.unwrapped.position == (1, 2) else obs), r, te, tr, info

    env = Bad(gym.make("avq/GridMaze-v0"))
    agent = avq.make_agent("avq-paper", env, seed=0)
    with pytest.raises(ValueError, match=r"observation at step \d+ has shape \(3,\)"):
        agent.learn(total_episodes=500)


def test_a_copy_of_the_maze_under_another_id_is_not_fused_and_learns_the_same():
    class CopyMaze(GridMaze):
        pass

    runs = []
    for env in (CopyMaze(), GridMaze()):
        agent = avq.make_agent("avq-paper", gym.wrappers.TimeLimit(env, 100), seed=5)
        runs.append(agent)
        agent.learn(total_episodes=80)
    assert runs[0]._fused_runner() is None and runs[1]._fused_runner() is not None
    assert np.array_equal(runs[0].q_, runs[1].q_)


def test_an_agent_trained_on_the_generic_path_pickles_and_goes_on_identically():
    import pickle

    agent = avq.make_agent("avq", gym.make("MountainCar-v0"), seed=3)
    agent.learn(total_episodes=3)
    twin = pickle.loads(pickle.dumps(agent))
    agent.learn(total_episodes=2)
    twin.learn(total_episodes=2)
    assert np.array_equal(agent.q_, twin.q_) and np.array_equal(agent.codebook_, twin.codebook_)


def test_a_reward_that_is_not_a_number_is_refused_naming_the_step():
    class Bad(gym.Wrapper):
        def step(self, action):
            obs, r, te, tr, info = self.env.step(action)
            return obs, ("oops" if self.env.unwrapped.position == (1, 2) else r), te, tr, info

    agent = avq.make_agent("avq-paper", Bad(gym.make("avq/GridMaze-v0")), seed=0)
    with pytest.raises(ValueError, match=r"reward 'oops' at step \d+ of episode \d+ is not a number"):
        agent.learn(total_episodes=500)
