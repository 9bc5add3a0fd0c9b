"""Kernel parameters declared once: an index enum per parameter array, and the packing generated from it.

A family's kernels read their hyper-parameters from small arrays (``P`` of floats, ``IP`` of ints), so
that a compiled loop takes one argument for all of them. Each array is declared by a
:class:`ParamIndex` subclass beside the rules that read it; a member's value is its index, and its
name in lower case is the agent parameter it holds::

    class FP(ParamIndex):
        D_MIN = auto()      # P[FP.D_MIN] holds agent.d_min
        SPLIT_THRESHOLD = auto()

:func:`pack_params` fills the array from the agent's parameters, so that a new parameter is one line
in the declaration (and its argument of the agent's ``__init__``). Numba compiles ``P[FP.D_MIN]`` to
a constant index, as it did the hand-kept integer constants these replace.
"""

from __future__ import annotations

from collections.abc import Mapping
from enum import IntEnum
from typing import Any

import numpy as np

__all__ = ["ParamIndex", "pack_params"]


class ParamIndex(IntEnum):
    """Indices into one parameter array: ``auto()`` numbers the members 0, 1, 2, ... in order."""

    @staticmethod
    def _generate_next_value_(name: str, start: int, count: int, last_values: list[Any]) -> int:
        return count


def pack_params(
    index: type[ParamIndex], values: Mapping[str, Any], dtype: Any = np.float64, out: np.ndarray | None = None
) -> np.ndarray:
    """The array of ``index``'s parameters: ``out[member] = values[member.name.lower()]``, for every member.

    Args:
        index: The declaration.
        values: The values by lower-case member name, usually the agent's parameters with the few that
            need converting (None as -1, a choice as its code) already converted.
        dtype: The array's type (ignored with ``out``).
        out: An array of ``len(index)`` to fill in place (the agent's own); a new one when None.

    Raises:
        KeyError: a member has no value (the declaration and the values disagree).
    """
    arr = np.zeros(len(index), dtype=dtype) if out is None else out
    for member in index:
        arr[member] = values[member.name.lower()]
    return arr
