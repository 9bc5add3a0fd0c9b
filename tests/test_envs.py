"""Every environment avq registers passes Gymnasium's own checker (a new one is picked up by its id)."""

import warnings

import gymnasium as gym
import pytest
from gymnasium.utils.env_checker import check_env

import avq  # noqa: F401  (registers the environments)

AVQ_IDS = sorted(env_id for env_id in gym.registry if env_id.startswith("avq/"))


def test_the_package_registers_its_mazes():
    assert {"avq/GridMaze-v0", "avq/RobotMaze-v0"} <= set(AVQ_IDS)


@pytest.mark.parametrize("env_id", AVQ_IDS)
def test_every_registered_environment_passes_check_env(env_id):
    env = gym.make(env_id)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped, skip_render_check=False)
