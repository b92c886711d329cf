"""Shared-memory rings: order, wrap-around, full rings and drop counts, in one process and
across a real second process (spawned, as the recorder is)."""

from __future__ import annotations

import multiprocessing
from collections.abc import Iterator
from multiprocessing.connection import Connection
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.errors import RecordingError
from hilrig.rig import TICK_DTYPE, Rows
from hilrig.rig.rings import Ring, RingSpec

ROW = np.dtype([("id", np.int64), ("value", np.float64, (3,))])


def value_of(i: int) -> tuple[float, float, float]:
    return (i + 0.25, -i - 0.5, i * 1e-3)


def fill_tick(slot: Rows, i: int) -> None:
    slot["t_ns"] = 1_000_000 * i
    slot["tick"] = i
    slot["force"] = np.arange(9) + i
    slot["contact"] = i % 4
    slot["desired_orientation"] = (0.0, 0.0, 0.0, 1.0)
    slot["queue_drops"] = -i


@pytest.fixture
def ring() -> Iterator[Ring]:
    ring = Ring.create(RingSpec.unique("test", ROW, 4))
    yield ring
    ring.unlink()
    ring.close()


# -- the other process: attaches, then reads or pushes on request --------------------------------


def serve(conn: Connection) -> None:
    """The second process: attach, read, push and close rings as the test asks."""
    rings: dict[str, Ring] = {}
    while True:
        command, spec, n = conn.recv()
        if command == "attach":
            rings[spec.name] = Ring.attach(spec)
            conn.send(None)
        elif command == "read":
            conn.send(rings[spec.name].read_available())
        elif command == "push_ticks":
            push_ticks(rings[spec.name], n)
            conn.send(None)
        elif command == "close":
            rings.pop(spec.name).close()
            conn.send(None)
        else:
            return


def push_ticks(ring: Ring, n: int) -> None:
    for i in range(n):
        slot = ring.reserve()
        if slot is not None:
            fill_tick(slot, i)
        ring.commit()


class Peer:
    """The test's handle on the second process."""

    def __init__(self, conn: Connection) -> None:
        self.conn = conn

    def ask(self, command: str, spec: RingSpec, n: int = 0) -> Any:
        self.conn.send((command, spec, n))
        return self.conn.recv()


@pytest.fixture(scope="module")
def peer() -> Iterator[Peer]:
    context = multiprocessing.get_context("spawn")
    conn, child = context.Pipe()
    process = context.Process(target=serve, args=(child,), daemon=True)
    process.start()
    yield Peer(conn)
    conn.send(("exit", None, 0))
    process.join(10)


# -- one process ---------------------------------------------------------------------------------


def test_rows_come_out_in_order_across_many_wraps(ring: Ring) -> None:
    consumer = Ring.attach(ring.spec)
    seen: list[int] = []
    for i in range(23):
        assert ring.push(i, value_of(i))
        if i % 3 == 2:
            rows = consumer.read_available()
            seen += rows["id"].tolist()
            assert rows["value"].tolist() == [list(value_of(j)) for j in rows["id"]]
    seen += consumer.read_available()["id"].tolist()
    consumer.close()
    assert seen == list(range(23))
    assert (ring.pushed, ring.dropped, ring.backlog) == (23, 0, 0)


def test_full_ring_refuses_rows_and_counts_each_refusal(ring: Ring) -> None:
    accepted = [ring.push(i, value_of(i)) for i in range(7)]
    assert accepted == [True] * 4 + [False] * 3
    assert (ring.pushed, ring.dropped, ring.backlog) == (4, 3, 4)
    consumer = Ring.attach(ring.spec)
    assert consumer.read_available()["id"].tolist() == [0, 1, 2, 3]
    assert ring.push(9, value_of(9))  # room again once read
    assert consumer.read_available()["id"].tolist() == [9]
    consumer.close()


def test_reserved_row_is_invisible_until_committed(ring: Ring) -> None:
    consumer = Ring.attach(ring.spec)
    slot = ring.reserve()
    assert slot is not None
    slot["id"] = 5
    assert len(consumer.read_available()) == 0
    assert ring.reserve() is slot  # reserving again hands out the same slot
    ring.commit()
    ring.commit()  # nothing reserved: publishes nothing
    assert consumer.read_available()["id"].tolist() == [5]
    del slot
    consumer.close()


def test_commit_after_a_refused_reservation_publishes_nothing(ring: Ring) -> None:
    for i in range(4):
        ring.push(i, value_of(i))
    assert ring.reserve() is None
    ring.commit()
    assert (ring.pushed, ring.dropped) == (4, 1)


def test_attach_refuses_a_missing_or_different_ring(ring: Ring) -> None:
    with pytest.raises(RecordingError, match="not a ring of 8 rows"):
        Ring.attach(RingSpec(ring.spec.name, ROW, 8))
    with pytest.raises(RecordingError, match="cannot attach"):
        Ring.attach(RingSpec("hilrig-test-missing", ROW, 4))


def test_close_refuses_while_a_slot_is_referenced_then_succeeds() -> None:
    ring = Ring.create(RingSpec.unique("test", ROW, 2))
    ring.unlink()
    slot = ring.reserve()
    with pytest.raises(RecordingError, match="still referenced"):
        ring.close()
    del slot
    ring.close()


def test_a_closed_ring_s_counters_read_as_they_were_at_its_close() -> None:
    ring = Ring.create(RingSpec.unique("test", ROW, 2))
    ring.unlink()
    for i in range(5):
        ring.push(i, value_of(i))
    before = (ring.pushed, ring.dropped, ring.backlog)
    ring.close()
    assert (ring.pushed, ring.dropped, ring.backlog) == before == (2, 3, 2)


def test_only_the_creator_unlinks(ring: Ring) -> None:
    consumer = Ring.attach(ring.spec)
    with pytest.raises(RecordingError, match="only its creator"):
        consumer.unlink()
    consumer.close()


# -- two processes -------------------------------------------------------------------------------


def test_tick_rows_pushed_by_another_process_arrive_whole(peer: Peer) -> None:
    ring = Ring.create(RingSpec.unique("tick", TICK_DTYPE, 5))
    try:
        peer.ask("attach", ring.spec)
        peer.ask("push_ticks", ring.spec, 8)  # 3 past capacity: refused
        rows = ring.read_available()
        assert ring.dropped == 3
        expected = np.zeros(5, TICK_DTYPE)
        for i in range(5):
            fill_tick(expected[i, ...], i)
        assert rows.tobytes() == expected.tobytes()
        peer.ask("close", ring.spec)
    finally:
        ring.unlink()
        ring.close()


OPS = st.lists(
    st.one_of(
        st.tuples(st.just("push"), st.integers(1, 10)),
        st.tuples(st.just("fill"), st.integers(1, 10)),
        st.tuples(st.just("abandon"), st.just(1)),
        st.tuples(st.just("read"), st.just(0)),
        st.tuples(st.just("put"), st.integers(0, 10)),
        st.tuples(st.just("put_first"), st.integers(0, 10)),
    ),
    max_size=25,
)


@settings(max_examples=60, deadline=None)
@given(capacity=st.integers(1, 6), ops=OPS)
def test_consumer_sees_exactly_the_committed_rows_in_order(
    peer: Peer, capacity: int, ops: list[tuple[str, int]]
) -> None:
    ring = Ring.create(RingSpec.unique("prop", ROW, capacity))
    source = np.zeros(10, dtype=ROW)  # a driver's rows: put_first stores their first n
    ring.feed_from(source)
    try:
        peer.ask("attach", ring.spec)
        pending: list[int] = []  # committed, not read yet: the model of the ring
        seen: list[int] = []
        committed: list[int] = []
        drops = 0
        for op, n in ops:
            if op == "read":
                rows = peer.ask("read", ring.spec)
                assert rows["id"].tolist() == pending
                assert rows["value"].tolist() == [list(value_of(i)) for i in pending]
                seen += pending
                pending = []
                continue
            if op in ("put", "put_first"):  # a batch by one compiled call, on the same ring
                first = len(committed) + drops
                batch = source[:n] if op == "put_first" else np.zeros(n, dtype=ROW)
                batch["id"] = np.arange(first, first + n)
                batch["value"] = np.reshape([value_of(i) for i in range(first, first + n)], (n, 3))
                room = min(n, capacity - len(pending))
                assert (ring.put_first(n) if op == "put_first" else ring.put(batch)) == room
                pending += list(range(first, first + room))
                committed += list(range(first, first + room))
                drops += n - room
                continue
            for _ in range(n):
                i = len(committed) + drops
                room = len(pending) < capacity
                if op == "push":
                    assert ring.push(i, value_of(i)) is room
                else:
                    slot = ring.reserve()
                    assert (slot is not None) is room
                    if slot is not None:
                        slot["id"], slot["value"] = (-1, value_of(-1))
                        if op == "fill":
                            slot["id"], slot["value"] = (i, value_of(i))
                            ring.commit()
                    del slot
                if room and op != "abandon":
                    pending.append(i)
                    committed.append(i)
                elif not room:
                    drops += 1
        seen += peer.ask("read", ring.spec)["id"].tolist()
        assert seen == committed
        assert (ring.pushed, ring.dropped) == (len(committed), drops)
        peer.ask("close", ring.spec)
    finally:
        ring.unlink()
        ring.close()


def test_a_ring_is_fed_only_rows_of_its_own_dtype_and_unbinds_them_at_close() -> None:
    ring = Ring.create(RingSpec.unique("fed", ROW, 4))
    try:
        with pytest.raises(RecordingError) as error:
            ring.feed_from(np.zeros(3, dtype=np.float64))
        assert str(error.value) == f"ring {ring.spec.name}: cannot be fed from rows of float64"
        with pytest.raises(RecordingError, match="put_first before feed_from"):
            ring.put_first(1)
        ring.feed_from(np.zeros(3, dtype=ROW))
        assert ring.put_first(2) == 2
    finally:
        ring.unlink()
        ring.close()  # the bound call's views of the block go first: it unmaps
    with pytest.raises(RecordingError, match="put_first before feed_from"):
        ring.put_first(1)
