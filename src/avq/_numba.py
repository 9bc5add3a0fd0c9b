"""Numba helpers that are not about any rule: views that skip reference counting, and calls that skip
the dispatcher."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numba
from numba import types
from numba.core import cgutils
from numba.core.compiler import CompilerBase, DefaultPassBuilder
from numba.core.datamodel.models import ArrayModel, StructModel
from numba.extending import intrinsic, register_model

__all__ = [
    "BorrowedArray",
    "BorrowedGenerator",
    "Compiled",
    "NoAliasPipeline",
    "borrowed",
    "borrowed_record",
    "row",
    "direct_call",
]


class BorrowedArray(types.Array):
    """The type of a borrowed view (:func:`borrowed`): an array whose references are not counted.

    Its values are laid out as an array's, but its data model has nothing to count, so that the compiler
    emits no reference counting for it at all (not even a call that finds no memory-info block). Handing a
    record of borrowed arrays to a function, inlined or not, copies the record and nothing else. Slices and
    other views of it are ordinary arrays (without memory-info block)."""

    def __init__(self, dtype, ndim, layout, readonly=False, aligned=True):
        name = f"borrowed {'readonly ' if readonly else ''}array({dtype}, {ndim}d, {layout})"
        super().__init__(dtype, ndim, layout, readonly=readonly, name=name, aligned=aligned)


@register_model(BorrowedArray)
class _BorrowedArrayModel(ArrayModel):
    def traverse(self, builder):
        return []  # (no member is counted: the memory-info pointer is null)


def _borrowed_type(arr: types.Array) -> BorrowedArray:
    if isinstance(arr, BorrowedArray):
        return arr
    return BorrowedArray(arr.dtype, arr.ndim, arr.layout, not arr.mutable, arr.aligned)


def _view(context, builder, arr: types.Array, out: BorrowedArray, value):
    """The code of a borrowed view of the array ``value`` (of type ``arr``): its fields but the memory-info
    block and the parent object, which are null."""
    src = context.make_array(arr)(context, builder, value=value)
    view = context.make_array(out)(context, builder)
    for field in ("nitems", "itemsize", "data", "shape", "strides"):
        setattr(view, field, getattr(src, field))
    view.meminfo = context.get_constant_null(types.MemInfoPointer(arr.dtype))
    view.parent = context.get_constant_null(types.pyobject)
    return view._getvalue()


class BorrowedGenerator(types.NumPyRandomGeneratorType):
    """The type of a borrowed ``numpy.random.Generator`` (:func:`borrowed`): the same generator, drawn from by
    the same compiled methods, whose reference the compiler does not count."""

    def __init__(self) -> None:
        super().__init__("borrowed NumPyRandomGeneratorType")
        self.name = "borrowed NumPyRandomGeneratorType"  # (the base class names every generator type alike)


@register_model(BorrowedGenerator)
class _BorrowedGeneratorModel(StructModel):
    def __init__(self, dmm, fe_type):
        # A Generator's members, laid out as Numba lays them out, with the memory-info pointer as a plain
        # pointer: nothing to count.
        members = [
            ("bit_generator", types.NumPyRandomBitGeneratorType("bit_generator")),
            ("meminfo", types.voidptr),
            ("parent", types.pyobject),
        ]
        super().__init__(dmm, fe_type, members)


def _borrowed(typingctx, arr):
    """A view of ``arr`` that does not own a reference to its memory, typed :class:`BorrowedArray`; or
    the generator ``arr`` typed :class:`BorrowedGenerator`.

    Numba counts references to an array with atomic increments and decrements each
    time the array is handed on (and each time a record of arrays is, for every array
    in it); in a hot loop that passes records of a dozen state arrays around, that
    counting costs more than the work. A borrowed view has no memory-info block and a
    type whose references the compiler does not count. The caller must keep ``arr``
    alive while the view is used: the fused loops borrow their arguments, which the
    Python caller holds, and never return the views. A ``Generator`` is counted in the
    same way (it holds a memory-info block) each time it is handed to a kernel that draws from it.
    """
    if isinstance(arr, types.NumPyRandomGeneratorType):
        gen = arr if isinstance(arr, BorrowedGenerator) else BorrowedGenerator()

        def codegen_generator(context, builder, signature, args):
            src = context.make_helper(builder, arr, value=args[0])
            view = context.make_helper(builder, gen)
            view.bit_generator = src.bit_generator
            view.meminfo = context.get_constant_null(types.voidptr)
            view.parent = src.parent
            return view._getvalue()

        return gen(arr), codegen_generator
    if not isinstance(arr, types.Array):
        return None
    out = _borrowed_type(arr)

    def codegen(context, builder, signature, args):
        return _view(context, builder, arr, out, args[0])

    return out(arr), codegen


def _borrowed_record(typingctx, rec):
    """``rec``, a record (NamedTuple) of arrays and numbers, with every array a borrowed view
    (:func:`borrowed`) and the numbers as they are: one function for every record of a fused loop."""
    if not isinstance(rec, types.BaseNamedTuple) or not all(
        isinstance(t, (types.Array, types.Number, types.Boolean)) for t in rec.types
    ):
        return None
    fields = [_borrowed_type(t) if isinstance(t, types.Array) else t for t in rec.types]
    out = types.BaseTuple.from_types(fields, rec.instance_class)

    def codegen(context, builder, signature, args):
        values = []
        for k, (t, field) in enumerate(zip(rec.types, fields)):
            value = builder.extract_value(args[0], k)
            values.append(_view(context, builder, t, field, value) if isinstance(t, types.Array) else value)
        return context.make_tuple(builder, out, values)

    return out(rec), codegen


def _row(typingctx, arr, i):
    """Row ``i`` (``0 <= i < arr.shape[0]``, unchecked, as indexing is) of the C-contiguous 2-D array ``arr``,
    as a borrowed view (:class:`BorrowedArray`): ``arr[i]`` without the reference counting of the view,
    which a loop that hands rows to the rules (``similar_profiles(Q[i], Q[j], rho)``) pays at every pair."""
    if not (isinstance(arr, types.Array) and arr.ndim == 2 and arr.layout == "C" and isinstance(i, types.Integer)):
        return None
    out = BorrowedArray(arr.dtype, 1, "C", not arr.mutable, arr.aligned)

    def codegen(context, builder, signature, args):
        src = context.make_array(arr)(context, builder, value=args[0])
        n = cgutils.unpack_tuple(builder, src.shape)[1]
        stride = cgutils.unpack_tuple(builder, src.strides)[1]
        k = context.cast(builder, args[1], signature.args[1], types.intp)
        view = context.make_array(out)(context, builder)
        context.populate_array(
            view,
            data=cgutils.gep_inbounds(builder, src.data, builder.mul(k, n)),
            shape=cgutils.pack_array(builder, [n]),
            strides=cgutils.pack_array(builder, [stride]),
            itemsize=src.itemsize,
            meminfo=None,
        )
        return view._getvalue()

    return out(arr, i), codegen


if TYPE_CHECKING:  # (what a compiled caller sees: one array in, a view of it out; likewise a record, a row)

    def borrowed(arr: Any) -> Any: ...

    def borrowed_record(rec: Any) -> Any: ...

    def row(arr: Any, i: int) -> Any: ...

else:
    borrowed = intrinsic(_borrowed)
    borrowed_record = intrinsic(_borrowed_record)
    row = intrinsic(_row)


class NoAliasPipeline(CompilerBase):
    """Numba's nopython pipeline, with the arguments of the compiled function declared ``noalias`` to LLVM:
    ``@njit(pipeline_class=NoAliasPipeline)``.

    The caller promises that no two arrays it hands the function share memory that the function writes. LLVM
    may then keep what it read from one array in registers while the function writes another: in a loop
    whose kernels read their state from small arrays (``S[CELL]``, ``P[GAMMA]``) between writes to others
    (``Q``, ``E``), that saves most of the reloads. Only for private functions whose every caller is known."""

    def define_pipelines(self) -> list:
        self.state.flags.noalias = True
        return [DefaultPassBuilder.define_nopython_pipeline(self.state)]


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
