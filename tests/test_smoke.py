"""Tiny-budget smoke tests: every agent name on every kind of environment, check_env on every
registered avq environment, and a save/load round trip for every agent."""

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import avq
from avq import AGENTS, make_agent

CARTPOLE_BOUNDS = [(-2.4, 2.4), (-3.0, 3.0), (-0.21, 0.21), (-3.5, 3.5)]

ENVS = {
    "grid-maze": lambda: gym.make("avq/GridMaze-v0"),
    "robot-maze": lambda: gym.make("avq/RobotMaze-v0"),
    "robot-maze-sonar": lambda: gym.make("avq/RobotMaze-v0", observe_sonar=True),
    "mountain-car": lambda: gym.make("MountainCar-v0"),
    "cartpole": lambda: gym.make("CartPole-v1"),
    "frozen-lake": lambda: gym.make("FrozenLake-v1"),
    "pendulum": lambda: gym.make("Pendulum-v1"),
}
#: The agents for continuous (Box) actions; every other agent needs Discrete actions.
CONTINUOUS_ACTIONS = {"avq-actions", "uniform-actions"}


def overrides(agent, env_name):
    if env_name == "cartpole" and agent in ("avq", "avq-plan", "grid", "grid-ps", "tiles"):
        return {"obs_bounds": CARTPOLE_BOUNDS}
    if env_name == "robot-maze-sonar" and agent in ("grid", "grid-ps"):
        return {"bins": 2}  # 18 dimensions: 10 bins each would be 10**18 rows
    return {}


def supported(agent, env_name):
    """Which combinations must work; the others must fail with a clear ValueError."""
    if env_name == "pendulum" or agent in CONTINUOUS_ACTIONS:
        return env_name == "pendulum" and agent in CONTINUOUS_ACTIONS
    return env_name != "frozen-lake" or agent in ("tabular", "tabular-ps")


def predict_obs(env):
    obs, _ = env.reset(seed=0)
    return obs


@pytest.mark.parametrize("env_name", sorted(ENVS))
@pytest.mark.parametrize("agent", sorted(AGENTS))
def test_every_agent_on_every_env_type(agent, env_name, tmp_path):
    env = ENVS[env_name]()
    if not supported(agent, env_name):
        with pytest.raises(ValueError, match="tabular|Box|Discrete"):
            make_agent(agent, env, seed=0, **overrides(agent, env_name))
        return
    model = make_agent(agent, env, seed=0, **overrides(agent, env_name)).learn(total_episodes=2)
    assert model.num_episodes == 2 and model.num_timesteps > 0
    h = model.episode_history()
    assert h["steps"].sum() == model.num_timesteps and model.n_cells >= 1
    obs = predict_obs(ENVS[env_name]())
    action, _ = model.predict(obs)
    assert env.action_space.contains(action)
    batch, _ = model.predict(np.stack([obs, obs]))
    assert batch.shape == (2, *env.action_space.shape)
    path = model.save(tmp_path / "m.zip")
    loaded = avq.load(path, env=ENVS[env_name]())
    assert type(loaded) is type(model) and loaded.get_params() == model.get_params()
    assert np.array_equal(loaded.predict(obs)[0], action)
    assert loaded.num_timesteps == model.num_timesteps


def test_tabular_on_continuous_observations_stops_at_max_states():
    model = make_agent("tabular", gym.make("MountainCar-v0"), seed=0, max_states=50)
    with pytest.raises(ValueError, match="max_states"):
        model.learn(total_episodes=1)


@pytest.mark.parametrize("env_id", sorted(k for k in gym.registry if k.startswith("avq/")))
def test_check_env_on_every_registered_avq_env(env_id):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(gym.make(env_id).unwrapped)


def test_registered_names():
    assert {"avq", "avq-paper", "avq-plan", "tabular", "tabular-ps", "grid", "grid-ps", "tiles"} <= set(AGENTS)


class StartAtOne(gym.ActionWrapper):
    """CartPole with its actions numbered 1 and 2 (``Discrete(2, start=1)``)."""

    def __init__(self, env):
        super().__init__(env)
        self.action_space = gym.spaces.Discrete(2, start=1)

    def action(self, action):
        assert action in (1, 2), f"action {action} is not one of this space's"
        return action - 1


@pytest.mark.parametrize("agent", sorted(set(AGENTS) - CONTINUOUS_ACTIONS))
def test_discrete_actions_not_numbered_from_zero_are_refused_with_the_wrapper_that_fixes_it(agent):
    env = StartAtOne(gym.make("CartPole-v1"))
    with pytest.raises(ValueError, match=r"numbered from 0, not Discrete\(2, start=1\).*TransformAction") as caught:
        make_agent(agent, env, seed=0, **overrides(agent, "cartpole"))
    fix = str(caught.value).split("number them from 0 with ")[1]
    # (the fix the message gives, as written, makes a space the agent takes and actions the task takes)
    fixed = eval(fix, {"gymnasium": gym, "env": env})  # noqa: S307
    make_agent(agent, fixed, seed=0, **overrides(agent, "cartpole")).learn(total_episodes=2)
