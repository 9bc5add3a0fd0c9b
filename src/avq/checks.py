"""A conformance check for agents, in the spirit of scikit-learn's ``check_estimator``.

``check_agent("tabular")`` runs every check of :data:`CHECKS` (parameter validation,
same seed same result, additive ``learn``, side-effect-free ``predict``, an exact
save/load round trip) on freshly made agents and raises an ``AssertionError`` naming
the first one that fails::

    from avq.checks import check_agent
    check_agent("avq", env_id="MountainCar-v0")
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from avq.agents.base import BaseAgent
from avq.agents.registry import AGENTS, make_agent

__all__ = ["check_agent", "CHECKS"]

#: Parameters every agent takes, with a value outside the allowed range.
_BAD_VALUES: dict[str, Any] = {"alpha": -0.5, "gamma": 1.5, "epsilon": 2.0, "lam": -1.0, "seed": -1}


class _Case:
    """Makes agents of one kind on fresh environments."""

    def __init__(
        self,
        agent: str | type[BaseAgent],
        env_id: str,
        env_kwargs: dict[str, Any],
        params: dict[str, Any],
        episodes: int,
    ) -> None:
        self.agent, self.env_id, self.env_kwargs, self.params, self.episodes = (
            agent,
            env_id,
            env_kwargs,
            params,
            episodes,
        )

    def env(self) -> gym.Env:
        from avq.envs import as_env

        return as_env(self.env_id, **self.env_kwargs)

    def make(self, seed: int = 0, **extra: Any) -> BaseAgent:
        params = {**self.params, **extra}
        if isinstance(self.agent, str):
            return make_agent(self.agent, self.env(), seed=seed, **params)
        return self.agent(self.env(), seed=seed, **params)


def _snapshot(agent: BaseAgent) -> dict[str, np.ndarray]:
    """Every learned array, the history without its wall-clock column, the counters, and the
    generator's next draw (taken from a twin, so the agent's stream is left as it was)."""
    meta, arrays = agent.state_dict()
    arrays = dict(arrays)
    arrays["history"] = arrays["history"][:, :-1]
    arrays["counters"] = np.array([agent.num_timesteps, agent.num_episodes])
    twin = np.random.Generator(getattr(np.random, meta["rng"]["bit_generator"])())
    twin.bit_generator.state = meta["rng"]
    arrays["rng"] = np.array([twin.random()])
    return arrays


def _assert_same(a: dict[str, np.ndarray], b: dict[str, np.ndarray], what: str) -> None:
    assert a.keys() == b.keys(), f"{what}: the learned arrays differ in names ({sorted(a)} != {sorted(b)})"
    for key in a:
        assert a[key].shape == b[key].shape and np.array_equal(a[key], b[key]), f"{what}: {key!r} differs"


def _observations(case: _Case, n: int = 16) -> np.ndarray:
    space = case.env().observation_space
    space.seed(0)
    return np.stack([np.asarray(space.sample(), dtype=np.float64) for _ in range(n)])


def check_parameters(case: _Case) -> None:
    """Construction checks each shared hyper-parameter and names it; get_params round-trips."""
    agent = case.make()
    params = agent.get_params()
    for name, bad in _BAD_VALUES.items():
        if name not in params:
            continue
        try:
            case.make(**{name: bad}) if name != "seed" else case.make(seed=bad)
        except ValueError as exc:
            assert name in str(exc), f"the error for {name}={bad!r} does not name the parameter: {exc}"
        else:
            raise AssertionError(f"{name}={bad!r} was accepted")
    again = type(agent)(case.env(), **params)
    assert again.get_params() == params, "get_params() does not round-trip through the constructor"
    assert type(agent).__name__ in repr(agent)


def check_seeding(case: _Case) -> None:
    """Same seed, same result; another seed, another result."""
    a = case.make(seed=11).learn(total_episodes=case.episodes)
    b = case.make(seed=11).learn(total_episodes=case.episodes)
    _assert_same(_snapshot(a), _snapshot(b), "two runs with the same seed")
    c = case.make(seed=12).learn(total_episodes=case.episodes)
    assert any(not np.array_equal(x, y) for x, y in zip(_snapshot(a).values(), _snapshot(c).values())), (
        "two different seeds gave identical results"
    )


def check_additive_learn(case: _Case) -> None:
    """learn(a) then learn(b) equals learn(a + b), in episodes and in steps (stopping inside an episode)."""
    whole = case.make(seed=5).learn(total_episodes=case.episodes)
    parts = case.make(seed=5)
    first = max(1, case.episodes // 2)
    parts.learn(total_episodes=first).learn(total_episodes=case.episodes - first)
    _assert_same(_snapshot(whole), _snapshot(parts), "learn in two calls (episodes)")
    steps = whole.num_timesteps
    by_steps = case.make(seed=5)
    by_steps.learn(total_timesteps=steps // 3).learn(total_timesteps=steps - steps // 3)
    assert by_steps.num_timesteps == steps
    _assert_same(_snapshot(whole), _snapshot(by_steps), "learn in two calls (steps)")


def check_predict(case: _Case) -> None:
    """predict: errors before learning; one action per observation, single or batched; queries change nothing."""
    fresh = case.make()
    try:
        fresh.predict(_observations(case, 1)[0])
    except RuntimeError:
        pass
    else:
        raise AssertionError("predict before learn did not raise RuntimeError")
    agent = case.make(seed=3).learn(total_episodes=case.episodes)
    before = _snapshot(agent)
    obs = _observations(case)
    space = agent.env.action_space
    batch, state = agent.predict(obs)
    assert isinstance(batch, np.ndarray), "a batch's predictions are not an array"
    assert space.shape is not None, "an action space without a shape"
    assert state is None and batch.shape == (len(obs), *space.shape)
    if isinstance(space, spaces.Discrete):
        assert batch.dtype == np.int64
    explore, _ = agent.predict(obs, deterministic=False)
    assert isinstance(explore, np.ndarray), "a batch's predictions are not an array"
    for k in range(len(obs)):
        single, _ = agent.predict(obs[k])
        assert space.contains(single) and space.contains(explore[k]), "an action outside the action space"
        if isinstance(space, spaces.Discrete):
            assert isinstance(single, int)
        assert np.array_equal(single, batch[k]), "single and batched predictions differ"
    _assert_same(before, _snapshot(agent), "predict changed the agent")
    for bad in (np.zeros(obs.shape[1] + 1), np.full(obs.shape[1], np.nan)):
        try:
            agent.predict(bad)
        except ValueError:
            pass
        else:
            raise AssertionError(f"predict accepted the bad observation {bad!r}")


def check_save_load(case: _Case) -> None:
    """A save/load round trip is exact, and the loaded agent learns on exactly as the original."""
    from avq.agents.base import load

    agent = case.make(seed=4).learn(total_episodes=case.episodes)
    with tempfile.TemporaryDirectory() as tmp:
        path = agent.save(Path(tmp) / "agent.zip")
        loaded = load(path, env=case.env())
    assert type(loaded) is type(agent) and loaded.get_params() == agent.get_params()
    _assert_same(_snapshot(agent), _snapshot(loaded), "save/load round trip")
    obs = _observations(case)
    assert np.array_equal(agent.predict(obs)[0], loaded.predict(obs)[0]), "predictions differ after loading"
    agent.learn(total_episodes=2)
    loaded.learn(total_episodes=2)
    _assert_same(_snapshot(agent), _snapshot(loaded), "learning on after loading")


#: Every check, in the order they run.
CHECKS: dict[str, Callable[[_Case], None]] = {
    "parameters": check_parameters,
    "seeding": check_seeding,
    "additive_learn": check_additive_learn,
    "predict": check_predict,
    "save_load": check_save_load,
}


def check_agent(
    agent: str | type[BaseAgent],
    env_id: str = "avq/GridMaze-v0",
    *,
    env_kwargs: dict[str, Any] | None = None,
    params: dict[str, Any] | None = None,
    episodes: int = 4,
) -> list[str]:
    """Run every check in :data:`CHECKS` on an agent; return their names, or raise ``AssertionError``.

    Args:
        agent: A registry name (see ``avq.AGENTS``) or an agent class.
        env_id: A registered Gymnasium id (Discrete actions, or Box actions for the agents made for them).
        env_kwargs: Arguments to ``gymnasium.make``.
        params: Agent parameters for every agent made.
        episodes: Episodes each check trains for.
    """
    if isinstance(agent, str) and agent not in AGENTS:
        raise ValueError(f"unknown agent {agent!r}; known agents: {', '.join(sorted(AGENTS))}")
    if not isinstance(agent, str) and not (isinstance(agent, type) and issubclass(agent, BaseAgent)):
        raise TypeError(f"agent must be a registry name or a BaseAgent subclass, not {agent!r}")
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes must be an integer >= 1, not {episodes!r}")
    case = _Case(agent, env_id, dict(env_kwargs or {}), dict(params or {}), episodes)
    for name, check in CHECKS.items():
        try:
            check(case)
        except AssertionError as exc:
            raise AssertionError(f"{agent} failed the {name!r} check: {exc}") from None
    return list(CHECKS)
