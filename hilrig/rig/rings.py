"""Single-producer single-consumer rings of fixed-dtype rows in shared memory.

The real-time loop (producer) hands rows to the recorder process (consumer) without locks,
system calls, pickling or allocation: :meth:`Ring.reserve` returns a writable view of the next
free slot (or None when the ring is full, which counts a drop), the loop fills it in place and
:meth:`Ring.commit` publishes it. The consumer copies every committed row out with
:meth:`Ring.read_available`. Neither side ever waits for the other.

Layout of the shared block: a 192-byte header of int64 words - a magic number, the row size and
capacity (checked on attach), then on its own 64-byte cache line the write index, the drop
count and the producer's last look at the read index (the producer's only), then on another line
the read index (the consumer's only) - followed by ``capacity`` rows. Indices count rows since
creation and never wrap; row ``i`` lives in slot ``i % capacity``. The producer keeps nothing
of its side outside the header, so its compiled twin (:mod:`hilrig.ring_kernels`: a batch
of rows stored by one call, :meth:`Ring.put`) may serve the same ring.

The creator is the producer: it touches every page of the block when creating it, so that
writing a row never faults. Lifetime: the creator (:meth:`Ring.create`) unlinks the block
(:meth:`Ring.unlink`) once both sides are done; every process, creator included, calls
:meth:`Ring.close` to unmap it. Attach only from processes started by :mod:`multiprocessing`
(spawn, forkserver or fork): they share the creator's resource tracker, which also unlinks the
block if the creator dies without doing so. A process with its own tracker (Python < 3.13)
would unlink the block when it exits.
"""

from __future__ import annotations

import gc
import secrets
from collections.abc import Callable
from dataclasses import dataclass
from multiprocessing import shared_memory
from typing import Any

import numpy as np
import numpy.typing as npt

from hilrig.array_table import ArrayTable, Layout, view1, view2
from hilrig.compiled import njit
from hilrig.errors import RecordingError
from hilrig.ring_kernels import DROPPED_AT, READ_AT, READ_SEEN_AT, WRITE_AT, put_rows

Rows = npt.NDArray[np.void]
"""Structured rows of a ring's dtype; a 0-d array of it is one writable row (a slot)."""

_MAGIC = int.from_bytes(b"HILRING1", "little")
_WORDS = 24  # header size in int64 words (192 bytes: three 64-byte cache lines)
_MAGIC_AT, _ITEMSIZE_AT, _CAPACITY_AT = 0, 1, 2
_HEADER_BYTES = _WORDS * 8


@dataclass(frozen=True)
class RingSpec:
    """What both sides need to find a ring: shared-memory ``name``, row ``dtype``, ``capacity``
    (rows). Picklable: hand it to the consumer process."""

    name: str
    dtype: np.dtype[Any]
    capacity: int

    def __post_init__(self) -> None:
        if self.capacity < 1:
            raise RecordingError(f"ring {self.name}: capacity must be >= 1, got {self.capacity}")

    @classmethod
    def unique(cls, label: str, dtype: np.dtype[Any], capacity: int) -> RingSpec:
        """A spec with a fresh name ``hilrig-<label>-<8 random hex digits>`` (a short label keeps
        it under macOS's 31 characters)."""
        return cls(f"hilrig-{label}-{secrets.token_hex(4)}", dtype, capacity)

    @property
    def nbytes(self) -> int:
        """Size of the shared block: header plus rows (bytes)."""
        return _HEADER_BYTES + self.capacity * self.dtype.itemsize


class Ring:
    """One end of a ring (use :meth:`create` or :meth:`attach`, not the constructor).

    Producer side: :meth:`reserve` / :meth:`commit`, or :meth:`push`. Consumer side:
    :meth:`read_available`. Each side belongs to one thread of one process; either side may be
    the creator.
    """

    def __init__(self, spec: RingSpec, shm: shared_memory.SharedMemory, *, owner: bool) -> None:
        self.spec = spec
        self._shm = shm
        self._owner = owner
        self._capacity = spec.capacity
        buf = shm.buf
        assert buf is not None  # None only after close
        # memoryview items are Python ints; an aligned 8-byte store is one instruction.
        self._words = buf[:_HEADER_BYTES].cast("q")
        self.header: npt.NDArray[np.int64] = np.frombuffer(buf, dtype=np.int64, count=_WORDS)
        """The header's words, for compiled code (:mod:`hilrig.ring_kernels`)."""
        # frombuffer keeps a memoryview of the block as the base of every view of the rows, so
        # the block cannot be unmapped under a live view (see close).
        self._data: Rows = np.frombuffer(
            buf, dtype=spec.dtype, count=spec.capacity, offset=_HEADER_BYTES
        )
        # One 0-d view per slot, made once: reserve() hands them out without allocating.
        self._slots = tuple(self._data[i, ...] for i in range(spec.capacity))
        self._read = self._words[READ_AT]  # consumer's copy of its own index
        self._reserved = False
        self._closed = False
        self._words_at_close: tuple[int, ...] = ()  # what the counters read once closed
        self._put_first: Callable[[int], int] = _not_fed

    @classmethod
    def create(cls, spec: RingSpec) -> Ring:
        """Create the shared block of ``spec``, empty. Raises RecordingError if it exists."""
        try:
            shm = shared_memory.SharedMemory(spec.name, create=True, size=spec.nbytes)
        except OSError as err:
            raise RecordingError(f"ring {spec.name}: cannot create ({err})") from err
        words = _header(shm)
        words[_ITEMSIZE_AT] = spec.dtype.itemsize
        words[_CAPACITY_AT] = spec.capacity
        words[_MAGIC_AT] = _MAGIC
        words.release()
        ring = cls(spec, shm, owner=True)
        # touch every page now: the producer's first pass would otherwise take a page fault
        # every few rows (tens of us each here), on the real-time thread
        ring._data.view(np.uint8)[:] = 0
        return ring

    @classmethod
    def attach(cls, spec: RingSpec) -> Ring:
        """Map the existing block of ``spec``. Raises RecordingError if it is missing or was
        made for another row size or capacity."""
        try:
            shm = shared_memory.SharedMemory(spec.name)
        except OSError as err:
            raise RecordingError(f"ring {spec.name}: cannot attach ({err})") from err
        found = (0, 0, 0)
        if shm.size >= spec.nbytes:
            words = _header(shm)
            found = (words[_MAGIC_AT], words[_ITEMSIZE_AT], words[_CAPACITY_AT])
            words.release()
        if found != (_MAGIC, spec.dtype.itemsize, spec.capacity):
            shm.close()
            raise RecordingError(
                f"ring {spec.name}: the shared block is not a ring of {spec.capacity} rows of"
                f" {spec.dtype.itemsize} bytes"
            )
        return cls(spec, shm, owner=False)

    # -- producer -----------------------------------------------------------------------------

    def reserve(self) -> Rows | None:
        """The next free slot as a writable 0-d row view, or None if the ring is full (counted
        in :attr:`dropped`). Fill it, then :meth:`commit`; until then it is invisible to the
        consumer, and calling reserve again returns the same slot."""
        index = self.reserve_index()
        return None if index < 0 else self._slots[index]

    def reserve_index(self) -> int:
        """Like :meth:`reserve`, but the slot's index into :attr:`rows` (-1 when full, counted),
        for compiled code that fills the row in place."""
        words = self._words
        write = words[WRITE_AT]
        if write - words[READ_SEEN_AT] >= self._capacity:
            words[READ_SEEN_AT] = words[READ_AT]
            if write - words[READ_SEEN_AT] >= self._capacity:
                words[DROPPED_AT] += 1
                self._reserved = False
                return -1
        self._reserved = True
        return write % self._capacity

    @property
    def rows(self) -> Rows:
        """Every slot of the ring (the shared block's rows), for :meth:`reserve_index`."""
        return self._data

    def commit(self) -> None:
        """Publish the reserved row; without a reservation (reserve returned None) do nothing."""
        if self._reserved:
            self._reserved = False
            # Publication order: the row's bytes were stored before this index store. x86-64
            # keeps stores in program order (TSO), and CPython performs the row stores and this
            # one in separate C calls the compiler cannot reorder, so a consumer that sees the
            # new index sees the row. Weakly ordered CPUs (ARM) would need a release fence here.
            self._words[WRITE_AT] += 1

    def put(self, rows: Rows) -> int:
        """Store and publish ``rows`` (of the ring's dtype) in one compiled call, each as
        :meth:`reserve_index` and :meth:`commit` would; returns how many the ring took (the
        others are drops, counted)."""
        stored: int = put_rows(self._data, self.header, rows)
        return stored

    def feed_from(self, source: Rows) -> None:
        """Bind :meth:`put_first` to ``source``, rows of the ring's dtype that stay the ones
        bound (a driver's decoder rows): a poll's rows then go into the ring by one compiled
        call that unboxes one array (:func:`put_first_rows`), not three."""
        if source.dtype != self.spec.dtype or not source.flags.c_contiguous:
            raise RecordingError(
                f"ring {self.spec.name}: cannot be fed from rows of {source.dtype}"
            )
        itemsize = self.spec.dtype.itemsize
        arrays = (
            self._data.view(np.uint8).reshape(self._capacity, itemsize),
            self.header,
            source.view(np.uint8).reshape(len(source), itemsize),
        )
        self._put_first = ArrayTable(arrays).bind(put_first_rows, _PUT_FIRST, last=(0,))

    def put_first(self, count: int) -> int:
        """:meth:`put` of the first ``count`` rows of the source bound by :meth:`feed_from`."""
        stored: int = self._put_first(count)
        return stored

    def push(self, *values: Any) -> bool:
        """Reserve, fill with ``values`` (one per field, in dtype order) and commit. Returns
        False if the ring was full (counted as a drop). Converts its values, so it is slower
        than filling a reserved slot in place."""
        slot = self.reserve()
        if slot is None:
            return False
        slot[()] = values
        self.commit()
        return True

    # -- consumer -----------------------------------------------------------------------------

    def read_available(self) -> Rows:
        """Copy out every committed row not read yet, oldest first, and release their slots."""
        write = self._words[WRITE_AT]  # load the index before the rows it publishes
        start = self._read % self._capacity
        count = write - self._read
        end = start + count
        if end <= self._capacity:
            rows = self._data[start:end].copy()
        else:
            rows = np.concatenate((self._data[start:], self._data[: end - self._capacity]))
        # The slots are handed back only after the copy: x86-64 never moves a store before
        # earlier loads, so the producer cannot overwrite a row still being copied.
        self._read = write
        self._words[READ_AT] = write
        return rows

    # -- both ---------------------------------------------------------------------------------

    @property
    def owner(self) -> bool:
        """True in the process that created the block (and must unlink it)."""
        return self._owner

    @property
    def pushed(self) -> int:
        """Rows committed since creation (the write index)."""
        return self._word(WRITE_AT)

    @property
    def dropped(self) -> int:
        """Rows refused because the ring was full, since creation."""
        return self._word(DROPPED_AT)

    @property
    def backlog(self) -> int:
        """Rows committed but not yet read by the consumer."""
        return self._word(WRITE_AT) - self._word(READ_AT)

    def _word(self, at: int) -> int:
        """A header word; once closed (also by another thread meanwhile: a status line read
        as the session ends), its value at the close."""
        try:
            return int(self._words[at])
        except ValueError:  # the header's view is released
            return self._words_at_close[at]

    def close(self) -> None:
        """Unmap the block in this process; call again once the views are gone if it raised.

        Raises RecordingError while a slot or field view handed out by :meth:`reserve` is still
        referenced: the block stays mapped rather than leave the view dangling.
        """
        if not self._closed:
            self._closed = True
            self._slots = ()
            self._put_first = _not_fed  # it holds views of the block
            del self._data, self.header
            self._words_at_close = tuple(self._words)
            self._words.release()
        try:
            self._shm.close()
        except BufferError:
            # numba's first compile of a kernel bound to the block (feed_from) can leave its
            # frames in a reference cycle that holds the bound views until a collection
            gc.collect()
            try:
                self._shm.close()
            except BufferError as err:
                raise RecordingError(
                    f"ring {self.spec.name}: cannot unmap while a reserved slot is still referenced"
                ) from err

    def unlink(self) -> None:
        """Remove the block's name (creator only; mappings stay valid until closed)."""
        if not self._owner:
            raise RecordingError(f"ring {self.spec.name}: only its creator unlinks it")
        self._shm.unlink()


_PUT_FIRST: Layout = ((np.uint8, 2), (np.int64, 1), (np.uint8, 2))  # slots, header, source


@njit(cache=True)
def put_first_rows(table: npt.NDArray[np.int64], count: int) -> int:
    """:func:`~hilrig.ring_kernels.put_rows` of the first ``count`` source rows, as bytes
    (_PUT_FIRST: the ring's slots, its header, the source rows)."""
    source = view2(table, 2, np.uint8)[:count]
    stored: int = put_rows(view2(table, 0, np.uint8), view1(table, 1, np.int64), source)
    return stored


def _not_fed(count: int) -> int:
    raise RecordingError("ring: put_first before feed_from (or after close)")


def _header(shm: shared_memory.SharedMemory) -> memoryview:
    """The header words of an open block (int64 items)."""
    buf = shm.buf
    assert buf is not None  # None only after close
    return buf[:_HEADER_BYTES].cast("q")
