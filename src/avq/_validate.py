"""The checks of hyper-parameters (the agents', the tile coder's), one function per kind of value.

Every check takes the parameter's name and value, returns the value in the form the
agent stores (a float, an int, a bool, a list), and raises a ``ValueError`` naming
the parameter, what it must be and the value given: ``alpha must be in (0.0, 1.0],
not 1.5`` (an :class:`InvalidParameterError`, public as ``avq.InvalidParameterError``). A bad
parameter is a ``ValueError`` everywhere in avq, whatever its type.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, TypeVar, overload

import numpy as np

__all__ = [
    "InvalidParameterError",
    "check_range",
    "check_int",
    "check_bool",
    "check_choice",
    "check_int_or_ints",
    "check_per_dimension",
    "check_optional",
    "check_sarsa_params",
    "check_planning_params",
    "SarsaSettings",
    "PlanningSettings",
]

T = TypeVar("T")


class InvalidParameterError(ValueError):
    """A hyper-parameter of the wrong type or out of range: ``alpha must be in (0.0, 1.0], not 1.5``.

    A ``ValueError`` (as scikit-learn's ``InvalidParameterError`` is), with the parameter's ``name``,
    what it must be (``expected``) and the ``value`` given. Public as ``avq.InvalidParameterError``.
    """

    def __init__(self, name: str, expected: str, value: Any) -> None:
        super().__init__(f"{name} must be {expected}, not {value!r}")
        self.name, self.expected, self.value = name, expected, value


# Raised from here, shown where users catch it: ``avq.InvalidParameterError`` in a traceback, not a private module.
InvalidParameterError.__module__ = "avq"


def _is_int(value: Any) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, np.integer))


def check_range(
    name: str, value: Any, low: float, high: float, *, low_open: bool = False, high_open: bool = False
) -> float:
    """``value`` as a float if it is a finite number in the interval (``inf`` only as a closed ``high``)."""
    interval = f"{'(' if low_open else '['}{low}, {high}{')' if high_open else ']'}"
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InvalidParameterError(name, f"a number in {interval}", value)
    v = float(value)
    ok = np.isfinite(v) or (v == high and high == np.inf)
    ok = ok and (v > low if low_open else v >= low) and (v < high if high_open else v <= high)
    if not ok:
        raise InvalidParameterError(name, f"in {interval}", value)
    return v


def check_int(name: str, value: Any, low: int) -> int:
    """``value`` as an int if it is an integer (not a bool) ``>= low``."""
    if not _is_int(value) or value < low:
        raise InvalidParameterError(name, f"an integer >= {low}", value)
    return int(value)


@overload
def check_bool(name: str, value: Any) -> bool: ...
@overload
def check_bool(name: str, value: Any, word: str) -> bool | str: ...
def check_bool(name: str, value: Any, word: str | None = None) -> bool | str:
    """``value`` as a bool if it is ``True`` or ``False`` (NumPy's included; not 0 or 1), or the string ``word``
    itself where one is given."""
    if word is not None and isinstance(value, str) and value == word:
        return value
    if not isinstance(value, (bool, np.bool_)):
        raise InvalidParameterError(name, "True or False" if word is None else f"True, False or {word!r}", value)
    return bool(value)


def check_choice(name: str, value: Any, choices: Sequence[str]) -> str:
    """``value`` if it is one of ``choices``."""
    if value not in choices:
        listed = " or ".join(map(repr, choices)) if len(choices) == 2 else f"one of {', '.join(map(repr, choices))}"
        raise InvalidParameterError(name, listed, value)
    return value


def check_int_or_ints(name: str, value: Any) -> int | list[int]:
    """An integer >= 1 for every dimension, or a non-empty sequence of them (one per dimension)."""

    def ok(v: Any) -> bool:
        return _is_int(v) and v >= 1

    if ok(value):
        return int(value)
    if isinstance(value, (list, tuple, np.ndarray)) and len(value) > 0 and all(ok(v) for v in value):
        return [int(v) for v in value]
    raise InvalidParameterError(name, "an integer >= 1 or a sequence of them (one per dimension)", value)


def check_per_dimension(name: str, value: int | list[int], n: int) -> int | list[int]:
    """A value of :func:`check_int_or_ints` once the number of observation dimensions ``n`` is known."""
    if isinstance(value, list) and len(value) != n:
        raise InvalidParameterError(name, f"an int or {n} ints (one per observation dimension)", value)
    return value


def check_optional(check: Callable[..., T], name: str, value: Any, *args: Any, **kwargs: Any) -> T | None:
    """None (the parameter is off), or ``check(name, value, *args, **kwargs)``; the message adds "or None"."""
    if value is None:
        return None
    try:
        return check(name, value, *args, **kwargs)
    except InvalidParameterError as exc:
        raise InvalidParameterError(exc.name, f"{exc.expected} or None", exc.value) from None


class SarsaSettings:
    """The hyper-parameters every Sarsa(λ) agent shares, as :func:`check_sarsa_params` stores them (a base
    class that declares them)."""

    alpha: float
    lam: float
    gamma: float
    epsilon: float
    q_init: float
    traces: str


class PlanningSettings:
    """The hyper-parameters every planning agent shares, as :func:`check_planning_params` stores them."""

    gamma: float
    epsilon: float
    v_opt: float | str
    v_min: float
    known_after: int
    n_backups: int
    tol: float


def check_sarsa_params(agent: Any, alpha: Any, lam: Any, gamma: Any, epsilon: Any, q_init: Any, traces: Any) -> None:
    """Check and store the hyper-parameters every Sarsa(λ) agent shares."""
    agent.alpha = check_range("alpha", alpha, 0.0, 1.0, low_open=True)
    agent.lam = check_range("lam", lam, 0.0, 1.0)
    agent.gamma = check_range("gamma", gamma, 0.0, 1.0)
    agent.epsilon = check_range("epsilon", epsilon, 0.0, 1.0)
    agent.q_init = check_range("q_init", q_init, -np.inf, np.inf, low_open=True, high_open=True)
    agent.traces = check_choice("traces", traces, ("replacing", "accumulating"))


def check_planning_params(
    agent: Any,
    gamma: Any,
    epsilon: Any,
    v_opt: Any,
    v_min: Any,
    known_after: Any,
    n_backups: Any,
    tol: Any,
    auto_v_opt: bool = False,
) -> None:
    """Check and store the hyper-parameters every planning agent shares (``auto_v_opt``: the agent also
    takes ``v_opt="auto"``)."""
    agent.gamma = check_range("gamma", gamma, 0.0, 1.0)
    agent.epsilon = check_range("epsilon", epsilon, 0.0, 1.0)
    if auto_v_opt and isinstance(v_opt, str) and v_opt == "auto":
        agent.v_opt = v_opt
    else:
        try:
            agent.v_opt = check_range("v_opt", v_opt, -np.inf, np.inf, low_open=True, high_open=True)
        except InvalidParameterError as exc:
            if not auto_v_opt:
                raise
            raise InvalidParameterError(exc.name, f"{exc.expected} or 'auto'", exc.value) from None
    agent.v_min = check_range("v_min", v_min, -np.inf, np.inf, low_open=True, high_open=True)
    if agent.v_opt != "auto" and agent.v_min > agent.v_opt:
        raise ValueError(
            f"v_min ({agent.v_min}) must not exceed v_opt ({agent.v_opt}): v_min is the floor of every "
            "value, v_opt what an untried decision is worth"
        )
    agent.known_after = check_int("known_after", known_after, 1)
    agent.n_backups = check_int("n_backups", n_backups, 0)
    agent.tol = check_range("tol", tol, 0.0, np.inf, low_open=True, high_open=True)
