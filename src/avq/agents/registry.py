"""Agents by name: ``make_agent("avq-paper", env)``, with defaults read from data files.

Each name's class, summary and defaults live in one YAML file, ``avq/agents/defaults/<name>.yaml``,
as RL Zoo keeps hyper-parameters per environment: a ``"*"`` entry used everywhere and, for some
environments, an entry that replaces it (all of it) there. An entry holds a one-line ``reason``, a
link to the ``results`` that chose it, its ``params``, and may start from another entry
(``base: {agent: ..., entry: ...}``, its params then added on top) or name another class
(``class``; none of the package's files does so today). A file's ``search`` is the space ``avq tune`` searches
(:data:`SEARCH`; :mod:`avq.tune` reads it). Explicit parameters given to :func:`make_agent`
win over the entry; the class's own signature defaults fill in what an entry leaves out.
:func:`make_agent` records on the agent which entry it used (``agent.defaults_used``, a
:class:`DefaultsUsed`) and ``avq train`` prints it.

The tables, all read from the files: :data:`AGENTS` (name -> its class and ``"*"`` defaults) and
:data:`DEFAULTS` (name -> entry key -> resolved params); :data:`ENTRIES` keeps each entry's reason
and link for the documentation.
"""

from __future__ import annotations

from importlib import resources
from typing import Any, NamedTuple

import gymnasium as gym
import yaml

from avq.agents.actions import ActionCodebookSarsa
from avq.agents.avq_sarsa import AVQSarsa
from avq.agents.base import BaseAgent
from avq.agents.baselines import GridSarsa, TabularSarsa, TileSarsa
from avq.agents.plan import PlanningAVQ, PrioritizedSweeping
from avq.agents.plan.merge import MODEL_MERGE_PARAMS
from avq.agents.plan.model import PLANNING_PARAMS
from avq.envs import split_env_id

__all__ = [
    "AGENTS",
    "DEFAULTS",
    "ENTRIES",
    "SEARCH",
    "SUMMARIES",
    "DefaultsUsed",
    "Entry",
    "agent_class",
    "agent_defaults",
    "defaults_key",
    "make_agent",
]

#: The classes a data file may name.
_CLASSES: dict[str, type[BaseAgent]] = {
    cls.__name__: cls
    for cls in (AVQSarsa, PlanningAVQ, TabularSarsa, GridSarsa, TileSarsa, PrioritizedSweeping, ActionCodebookSarsa)
}


class Entry(NamedTuple):
    """One entry of an agent's data file, resolved: the class, the parameters, and why."""

    cls: type[BaseAgent]
    params: dict[str, Any]
    reason: str
    #: The docs page (relative to the docs' root) whose section holds the measurements that chose it.
    results: str


class _Agent(NamedTuple):
    summary: str
    entries: dict[str, Entry]


def _read(name: str) -> dict[str, Any]:
    text = resources.files("avq.agents").joinpath("defaults").joinpath(f"{name}.yaml").read_text(encoding="utf-8")
    # (libyaml's parser where PyYAML has it: the same tables, read at every import, ten times faster)
    data = yaml.load(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    if not isinstance(data, dict) or not {"class", "summary", "entries"} <= set(data):
        raise ValueError(f"avq/agents/defaults/{name}.yaml: needs 'class', 'summary' and 'entries'")
    return data


def _names() -> list[str]:
    return sorted(
        p.name[: -len(".yaml")]
        for p in resources.files("avq.agents").joinpath("defaults").iterdir()
        if p.name.endswith(".yaml")
    )


def _load_all() -> dict[str, _Agent]:
    raw = {name: _read(name) for name in _names()}
    done: dict[tuple[str, str], Entry] = {}

    def resolve(name: str, key: str, seen: tuple[tuple[str, str], ...] = ()) -> Entry:
        if (name, key) in done:
            return done[(name, key)]
        if (name, key) in seen:
            raise ValueError(f"avq/agents/defaults/{name}.yaml: entry {key!r} is its own base")
        e = raw[name]["entries"][key]
        params: dict[str, Any] = {}
        if "base" in e:
            base = resolve(e["base"].get("agent", name), e["base"]["entry"], (*seen, (name, key)))
            params.update(base.params)
        params.update(e.get("params") or {})
        cls = _CLASSES[e.get("class", raw[name]["class"])]
        done[(name, key)] = Entry(cls, params, e["reason"], e["results"])
        return done[(name, key)]

    return {
        name: _Agent(" ".join(data["summary"].split()), {key: resolve(name, key) for key in data["entries"]})
        for name, data in raw.items()
    }


_TABLE = _load_all()

#: name -> {entry key ("*" or an environment id) -> Entry}.
ENTRIES: dict[str, dict[str, Entry]] = {name: agent.entries for name, agent in _TABLE.items()}
#: name -> {entry key -> the defaults there}.
DEFAULTS: dict[str, dict[str, dict[str, Any]]] = {
    name: {key: e.params for key, e in entries.items()} for name, entries in ENTRIES.items()
}
#: name -> (its class, its ``"*"`` defaults): the one table of names.
AGENTS: dict[str, tuple[type[BaseAgent], dict[str, Any]]] = {
    name: (entries["*"].cls, entries["*"].params) for name, entries in ENTRIES.items()
}
#: name -> one paragraph on what the agent is (the reference's section per agent).
SUMMARIES: dict[str, str] = {name: agent.summary for name, agent in _TABLE.items()}


def _search(name: str) -> dict[str, Any]:
    """The file's ``search``: parameter -> its range (checked by :mod:`avq.tune`), or another agent's name."""
    space = _read(name).get("search") or {}
    return _search(space) if isinstance(space, str) else dict(space)


#: name -> the space ``avq tune`` searches by default: parameter -> ``{low, high, log, type}`` or ``{choices}``.
SEARCH: dict[str, dict[str, Any]] = {name: _search(name) for name in _names()}


class DefaultsUsed(NamedTuple):
    """Which defaults :func:`make_agent` gave an agent: ``DEFAULTS[name][key]``, then ``explicit``."""

    name: str
    env_id: str | None
    #: The entry of ``DEFAULTS[name]`` used: ``"*"`` or an environment id.
    key: str
    #: The parameters given explicitly, which won over the entry.
    explicit: dict[str, object]

    def __str__(self) -> str:
        which = "the general defaults" if self.key == "*" else f"the {self.key} defaults"
        explicit = ", ".join(f"{k}={v!r}" for k, v in self.explicit.items()) or "none"
        return (
            f"agent {self.name} on {self.env_id or 'an unregistered environment'}: {which} of {self.name} "
            f"(avq/agents/defaults/{self.name}.yaml, entry {self.key!r}); explicit: {explicit}"
        )


def defaults_key(name: str, env_id: str | None = None) -> str:
    """The entry of ``DEFAULTS[name]`` that holds agent ``name``'s defaults on ``env_id``: the id or ``"*"``
    (the id without the module of Gymnasium's ``"module:id"`` form, as the entries are keyed)."""
    if name not in DEFAULTS:
        raise ValueError(f"unknown agent {name!r}; known agents: {', '.join(sorted(DEFAULTS))}")
    env_id = None if env_id is None else split_env_id(env_id)[1]
    return env_id if env_id is not None and env_id != "*" and env_id in DEFAULTS[name] else "*"


def agent_class(name: str, env_id: str | None = None) -> type[BaseAgent]:
    """The class of agent ``name`` on environment ``env_id`` (an entry of the agent's defaults file may name
    its own)."""
    key = defaults_key(name, env_id)  # (an unknown name raises here)
    return ENTRIES[name][key].cls


def agent_defaults(name: str, env_id: str | None = None) -> dict[str, Any]:
    """The defaults of agent ``name``, on environment ``env_id`` if it has defaults of its own there."""
    key = defaults_key(name, env_id)  # (an unknown name raises here)
    return dict(DEFAULTS[name][key])


def _env_id(env: gym.Env | str) -> str | None:
    """The registered id of ``env``: its ``spec``, or for an environment built without ``gymnasium.make``
    the id registered for its class; None when a wrapper changed its observations (``IrrelevantDims``, say):
    the defaults of a task are chosen for its own observations."""
    if isinstance(env, str):
        return split_env_id(env)[1]  # (without the module of Gymnasium's "module:id" form)
    if not isinstance(env, gym.Env) or env.observation_space != env.unwrapped.observation_space:
        return None  # (not an env: the agent's constructor says what it needs)
    spec = getattr(env, "spec", None)
    if spec is not None:
        return spec.id
    cls = type(env.unwrapped)
    target = f"{cls.__module__}:{cls.__qualname__}"
    return next((env_id for env_id, s in gym.registry.items() if s.entry_point == target), None)


def make_agent(name: str, env: gym.Env | str, seed: int | None = None, **overrides: Any) -> BaseAgent:
    """Create the agent registered as ``name`` with its defaults, updated by ``overrides``.

    The names, with each one's rules and defaults, are in ``avq/agents/defaults/``. Some agents have
    defaults of their own on some environments: ``avq`` on ``avq/GridMaze-v0`` uses the collision-driven maze
    rules, and on ``avq/RobotMaze-v0`` the planning agent with merging. The environment is recognised by its registered id
    (``env.spec.id``, or the id registered for its class when it was built without ``gymnasium.make``);
    a wrapper that changes the observations (as :class:`avq.envs.IrrelevantDims` does) makes it another
    task, which gets the general defaults.
    The agent's ``defaults_used`` says which entry was used and which parameters were explicit.

    Args:
        name: A registered name, such as ``"avq-paper"``, ``"avq"`` or ``"tabular"``.
        env: A Gymnasium environment, or a registered id to make one.
        seed: The seed of the agent's generators (None: fresh entropy).
        overrides: Parameters of the agent's class, which win over the defaults.

    Returns:
        The agent, not yet trained.

    Raises:
        ValueError: unknown name, or an override that is not a parameter of the agent.
    """
    env_id = _env_id(env)
    key = defaults_key(name, env_id)  # (an unknown name raises here)
    cls = agent_class(name, env_id)
    varies = len({e.cls for e in ENTRIES[name].values()}) > 1
    if "seed" in overrides:
        raise ValueError("seed is not an agent parameter here: pass it as seed= (on the command line, --seed)")
    valid = set(cls._param_names()) - {"seed"}
    unknown = sorted(set(overrides) - valid)
    for family, what, who in (
        (PLANNING_PARAMS, "planning over a learned model", "plan"),
        (MODEL_MERGE_PARAMS, "merging cells under a learned model", "merge under a model"),
    ):
        given = [p for p in unknown if p in family]
        if given:
            has = lambda n, family=family: set(family) <= set(agent_class(n, env_id)._param_names())  # noqa: E731
            where = f" on {env_id or 'this environment'}" if varies else ""
            raise ValueError(
                f"{given[0]!r} is an option of {what}, and agent {name!r} has no model{where}; "
                f"the agents that {who}{where} are {', '.join(repr(n) for n in AGENTS if has(n))}"
            )
    if unknown:
        raise ValueError(
            f"unknown parameter {unknown[0]!r} for agent {name!r}"
            + (f" on {env_id or 'this environment'} (class {cls.__name__})" if varies else "")
            + f"; its parameters: {', '.join(sorted(valid))}"
        )
    agent = cls(env, **{**DEFAULTS[name][key], **overrides, "seed": seed})
    agent.defaults_used = DefaultsUsed(name, env_id, key, dict(overrides))
    return agent
