"""Numba helpers that are not about any rule: views that skip reference counting, and calls that skip
the dispatcher."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numba
from numba import types
from numba.extending import intrinsic

__all__ = ["Compiled", "borrowed", "direct_call"]


def _borrowed(typingctx, arr):
    """A view of ``arr`` that does not own a reference to its memory.

    Numba counts references to an array with atomic increments and decrements each
    time the array is handed on, and in a hot loop that passes a dozen state arrays
    around, those atomics cost about a third of the time. A borrowed view has no
    memory-info block, so counting it is a null check. The caller must keep ``arr``
    alive while the view is used: the fused loops borrow their arguments, which the
    Python caller holds, and never return the views.
    """
    if not isinstance(arr, types.Array):
        return None

    def codegen(context, builder, signature, args):
        src = context.make_array(arr)(context, builder, value=args[0])
        view = context.make_array(arr)(context, builder)
        for field in ("nitems", "itemsize", "data", "shape", "strides"):
            setattr(view, field, getattr(src, field))
        view.meminfo = context.get_constant_null(types.MemInfoPointer(arr.dtype))
        view.parent = context.get_constant_null(types.pyobject)
        return view._getvalue()

    return arr(arr), codegen


if TYPE_CHECKING:  # (what a compiled caller sees: one array in, a view of it out)

    def borrowed(arr: Any) -> Any: ...

else:
    borrowed = intrinsic(_borrowed)


def direct_call(dispatcher: Any, args: tuple) -> Any:
    """The compiled function that Numba's ``dispatcher`` runs for ``args`` (which it has just run), or None.

    Calling it directly skips the dispatcher's type resolution (about 0.5 µs a call). It converts its
    arguments to the types it was compiled for without checking them, so the caller calls it only with
    arguments of the same types: our own arrays, an observation of the same dtype, shape and (C)
    layout, a reward of the same Python type, and booleans.
    """
    try:
        key = tuple(numba.typeof(v) for v in args)
    except ValueError:
        return None
    compiled = dispatcher.overloads.get(key)
    return None if compiled is None else compiled.entry_point


class Compiled:
    """A compiled function called from Python: through Numba's dispatcher the first time, then directly
    (:func:`avq._numba.direct_call`). Typing a record of arrays at every call costs the dispatcher several µs,
    as much as a sweep of a small model. Only for calls whose arguments keep their types: records whose arrays
    are reallocated with the same dtypes, dimensions and layout (:meth:`avq.agents.plan.model.Model.reserve`), ints, floats, bools."""

    def __init__(self, dispatcher: Any) -> None:
        self.dispatcher = dispatcher
        self.entry: Any = None

    def __getstate__(self) -> dict[str, Any]:
        return {"dispatcher": self.dispatcher, "entry": None}  # (the entry point cannot be pickled; found again)

    def __call__(self, *args: Any) -> Any:
        if self.entry is not None:
            return self.entry(*args)
        out = self.dispatcher(*args)
        self.entry = direct_call(self.dispatcher, args)
        return out
