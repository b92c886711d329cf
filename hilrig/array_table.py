"""A kernel's arrays passed by address: one argument to unbox a call instead of dozens.

numba unboxes every array argument on every call: about 45 ns an array here (a memory-info
block made and freed for each), so the compiled tick, which takes 25 arrays, spent more than a
microsecond a call before its first instruction, and a slow machine five times that. An
:class:`ArrayTable` holds a kernel's arrays (references kept: they live as long as the table)
and a (n, 4) int64 table of their addresses and shapes; the kernel's *entry*, compiled, rebuilds
each array from its row with :func:`view1`, :func:`view2` or :func:`view3` (no copy, nothing
allocated) and calls the kernel; :meth:`ArrayTable.bind` binds the entry to the table.

The entry states each array's dtype and number of dimensions, in the table's order: a table
made from other arrays than the entry expects is refused by :meth:`ArrayTable.bind` when its
``layout`` differs (each kernel module keeps its entry and its layout side by side). Only
C-contiguous arrays can be tabled, and a tabled array must never be resized. The entry's views
are writable even of a read-only array (the robot chain's constants are): numba's typing, which
refuses a store into a read-only argument, no longer sees them, so the kernel must not write
what it was given read-only.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import partial
from typing import Any

import numpy as np
from numba import typeof, types
from numba.core import cgutils
from numba.extending import intrinsic
from numba.np.numpy_support import carray
from numpy.typing import NDArray

from hilrig.compiled import njit
from hilrig.errors import ParameterError

ADDRESS, SHAPE = 0, 1  # columns of a table's row: the data's address, then up to 3 extents
MAX_DIMS = 3

Layout = tuple[tuple[Any, int], ...]  # (dtype, dimensions) of each array, in the table's order


@intrinsic
def _pointer(typingctx: Any, address: Any) -> tuple[Any, Any]:
    """The int64 ``address`` as a ``void*``."""

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        return builder.inttoptr(args[0], cgutils.voidptr_t)

    return types.voidptr(types.int64), codegen


@njit(cache=True, inline="always")
def _data(table: NDArray[np.int64], i: int) -> Any:
    """Row ``i``'s array data, as a pointer."""
    return _pointer(table[i, ADDRESS])  # type: ignore[call-arg]  # numba supplies the context


@njit(cache=True, inline="always")
def view1(table: NDArray[np.int64], i: int, dtype: Any) -> Any:
    """Row ``i`` of ``table`` as the 1-d array of ``dtype`` it was made from."""
    return carray(_data(table, i), (table[i, SHAPE],), dtype)


@njit(cache=True, inline="always")
def view2(table: NDArray[np.int64], i: int, dtype: Any) -> Any:
    """Row ``i`` of ``table`` as the 2-d array of ``dtype`` it was made from."""
    return carray(_data(table, i), (table[i, SHAPE], table[i, SHAPE + 1]), dtype)


@njit(cache=True, inline="always")
def view3(table: NDArray[np.int64], i: int, dtype: Any) -> Any:
    """Row ``i`` of ``table`` as the 3-d array of ``dtype`` it was made from."""
    shape = (table[i, SHAPE], table[i, SHAPE + 1], table[i, SHAPE + 2])
    return carray(_data(table, i), shape, dtype)


class ArrayTable:
    """The addresses and shapes of ``arrays`` (each C-contiguous, 1 to 3 dimensions), which
    the table keeps alive; ``names`` name them in errors."""

    def __init__(self, arrays: Sequence[NDArray[Any]], names: Sequence[str] = ()) -> None:
        self.arrays = tuple(arrays)
        self.table = np.zeros((len(self.arrays), 1 + MAX_DIMS), dtype=np.int64)
        for i, array in enumerate(self.arrays):
            name = names[i] if i < len(names) else f"array {i}"
            if not isinstance(array, np.ndarray):
                raise ParameterError(
                    f"array table: {name} is a {type(array).__name__}, not an array"
                )
            if not 1 <= array.ndim <= MAX_DIMS:
                raise ParameterError(
                    f"array table: {name} has {array.ndim} dimensions, not 1 to {MAX_DIMS}"
                )
            if not array.flags.c_contiguous:
                raise ParameterError(f"array table: {name} is not C-contiguous (a strided view?)")
            self.table[i, ADDRESS] = array.ctypes.data
            self.table[i, SHAPE : SHAPE + array.ndim] = array.shape

    @property
    def layout(self) -> Layout:
        """Each array's dtype and number of dimensions, in order."""
        return tuple((array.dtype, array.ndim) for array in self.arrays)

    def bind(self, entry: Any, layout: Layout, *, last: tuple[Any, ...]) -> Callable[..., Any]:
        """``entry`` (an ``@njit`` function of the table and trailing scalars like ``last``)
        bound to this table, compiled (or loaded from the cache) now; refused if this table's
        arrays are not those of ``layout``, the entry's."""
        expected = tuple((np.dtype(dtype), ndim) for dtype, ndim in layout)
        if self.layout != expected:
            raise ParameterError(
                f"array table: arrays {_describe(self.layout)} given to an entry that takes "
                f"{_describe(expected)}"
            )
        signature = (typeof(self.table), *(typeof(value) for value in last))  # type: ignore[no-untyped-call]
        call = partial(entry.compile(signature), self.table)
        vars(call)["arrays"] = self  # kept with the call: the addresses stay valid
        return call


def _describe(layout: Layout) -> str:
    return "(" + ", ".join(f"{np.dtype(dtype).str}/{ndim}d" for dtype, ndim in layout) + ")"
