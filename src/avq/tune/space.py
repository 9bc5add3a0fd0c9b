"""A search space: parameter -> its range, as declared beside an agent's defaults (the ``search`` of
``avq/agents/defaults/<name>.yaml``) or in a user's YAML file given to ``avq tune --space``.

A range is a mapping: ``{low, high}`` (a float, or with ``type: int`` an integer; ``log: true`` samples
it on a log scale) or ``{choices: [...]}`` (a categorical of numbers, strings, booleans or null).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any

from avq._io import read_yaml

__all__ = ["Range", "read_space", "check_space", "agent_space"]

_KEYS = {"low", "high", "log", "type", "choices"}
_TYPES = ("float", "int", "categorical")


@dataclass(frozen=True)
class Range:
    """One parameter's range: ``kind`` is ``float``, ``int`` or ``categorical`` (then ``choices``)."""

    name: str
    kind: str
    low: float | None = None
    high: float | None = None
    log: bool = False
    choices: tuple[Any, ...] = ()

    def suggest(self, trial: Any) -> Any:
        """A value drawn for an Optuna ``trial`` (by the study's sampler)."""
        if self.kind == "categorical":
            return trial.suggest_categorical(self.name, list(self.choices))
        if self.kind == "int":
            return trial.suggest_int(self.name, int(self.low or 0), int(self.high or 0), log=self.log)
        return trial.suggest_float(self.name, float(self.low or 0.0), float(self.high or 0.0), log=self.log)


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _range(name: str, spec: Any, where: str) -> Range:
    def bad(why: str) -> ValueError:
        return ValueError(f"{where}: parameter {name!r}: {why}")

    if not isinstance(spec, dict):
        raise bad(f"give a mapping such as {{low: 0.01, high: 1.0, log: true}} or {{choices: [...]}}, not {spec!r}")
    unknown = sorted(set(spec) - _KEYS)
    if unknown:
        raise bad(f"unknown key {unknown[0]!r}; a range has {', '.join(sorted(_KEYS))}")
    kind = spec.get("type") or ("categorical" if "choices" in spec else None)
    if kind is None:
        kind = (
            "int"
            if all(isinstance(spec.get(k), int) and not isinstance(spec.get(k), bool) for k in ("low", "high"))
            else "float"
        )
    if kind not in _TYPES:
        raise bad(f"type must be one of {', '.join(_TYPES)}, not {kind!r}")
    if kind == "categorical":
        choices = spec.get("choices")
        if not isinstance(choices, list) or not choices:
            raise bad(f"choices must be a non-empty list, not {choices!r}")
        for c in choices:
            if c is not None and not isinstance(c, (bool, int, float, str)):
                raise bad(f"a choice must be a number, a string, true/false or null, not {c!r}")
        if set(spec) - {"choices", "type"}:
            raise bad("give either choices or low and high, not both")
        return Range(name, kind, choices=tuple(choices))
    low: Any = spec.get("low")
    high: Any = spec.get("high")
    log = spec.get("log", False)
    if not (_number(low) and _number(high)):
        raise bad(f"low and high must be numbers, not {low!r} and {high!r}")
    if kind == "int" and not (float(low).is_integer() and float(high).is_integer()):
        raise bad(f"an int range needs integer low and high, not {low!r} and {high!r}")
    if not low < high:
        raise bad(f"low must be below high, not {low!r} and {high!r}")
    if not isinstance(log, bool):
        raise bad(f"log must be true or false, not {log!r}")
    if log and low <= 0:
        raise bad(f"a log scale needs low > 0, not {low!r}")
    return Range(
        name, kind, float(low) if kind == "float" else int(low), float(high) if kind == "float" else int(high), log
    )


def parse_space(raw: Any, where: str) -> dict[str, Range]:
    """A checked space from its YAML mapping (``where`` names it in errors)."""
    if not isinstance(raw, dict) or not raw:
        raise ValueError(f"{where}: a search space is a non-empty mapping of parameter -> range, not {raw!r}")
    return {str(name): _range(str(name), spec, where) for name, spec in raw.items()}


def read_space(path: str | os.PathLike) -> dict[str, Range]:
    """A user's search space from a YAML file (the format of the defaults' ``search``)."""
    raw = read_yaml(path, f"search space {path}")
    if isinstance(raw, dict) and set(raw) == {"search"}:
        raw = raw["search"]  # (a file holding the section as written in the defaults)
    return parse_space(raw, f"search space {path}")


def agent_space(agent: str) -> dict[str, Range]:
    """The space declared beside agent ``agent``'s defaults; a ValueError when it has none."""
    from avq.agents.registry import SEARCH, defaults_key

    defaults_key(agent)  # (an unknown name raises here)
    where = f"avq/agents/defaults/{agent}.yaml 'search'"
    if not SEARCH[agent]:
        raise ValueError(f"agent {agent!r} declares no search space ({where}); give one with --space FILE.yaml")
    return parse_space(SEARCH[agent], where)


def check_space(space: dict[str, Range], agent: str, env_id: str, fixed: dict[str, Any], where: str) -> None:
    """Every parameter of ``space`` is one of the agent's on ``env_id`` and is not also fixed (``--set``)."""
    from avq.agents.registry import agent_class

    cls = agent_class(agent, env_id)
    valid = set(cls._param_names()) - {"seed"}
    for name in space:
        if name not in valid:
            raise ValueError(
                f"{where} names {name!r}, which is not a parameter of agent {agent!r} on {env_id} "
                f"(class {cls.__name__}); its parameters: {', '.join(sorted(valid))}. "
                "Remove it from the space or give another with --space FILE.yaml"
            )
        if name in fixed:
            raise ValueError(
                f"{name!r} is both searched ({where}) and fixed with --set; drop the --set, or search without it: "
                "--space FILE.yaml with a 'search' that leaves it out (docs/how-to/tuning.md)"
            )
