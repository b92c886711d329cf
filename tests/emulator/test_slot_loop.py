"""The emulated rig's slot loop serves its watched descriptors (epoll) on real socket pairs: each
readable one's handler once a slot, none after unwatch, the latest handler of a descriptor
watched twice, and a descriptor closed before its unwatch, or its number reused, handled."""

from __future__ import annotations

import socket

from hilrig.emulator.slots import SlotLoop

PERIOD_NS = 1_000_000


def run_slots(loop: SlotLoop, slots: int) -> None:
    """Run ``loop`` in this thread until it has run ``slots`` more slots."""
    target = loop.slots + slots

    def on_slot(slot_ns: int, now_ns: int) -> None:
        if loop.slots + 1 >= target:
            loop.stop()

    loop._on_slot = on_slot
    loop._stopping = False
    loop.run()


def drain(sock: socket.socket, seen: list[str], name: str) -> None:
    sock.recv(4096)
    seen.append(name)


def test_readable_descriptors_are_served_and_unwatched_ones_are_not() -> None:
    loop = SlotLoop(PERIOD_NS, lambda slot_ns, now_ns: None)
    (a, a_peer), (b, b_peer) = socket.socketpair(), socket.socketpair()
    seen: list[str] = []
    loop.watch(a.fileno(), lambda: drain(a, seen, "a"))
    loop.watch(b.fileno(), lambda: drain(b, seen, "b"))
    a_peer.send(b"x")
    run_slots(loop, 3)
    assert seen == ["a"]  # b had nothing: not served
    loop.unwatch(a.fileno())
    a_peer.send(b"y")
    b_peer.send(b"z")
    run_slots(loop, 3)
    assert seen == ["a", "b"]
    assert a.recv(4096) == b"y"  # left unread: a is no longer watched
    loop.watch(b.fileno(), lambda: drain(b, seen, "b again"))  # a second handler replaces it
    b_peer.send(b"w")
    run_slots(loop, 3)
    assert seen == ["a", "b", "b again"]
    for sock in (a, a_peer, b, b_peer):
        sock.close()


def test_a_descriptor_closed_before_its_unwatch_and_its_number_reused_are_handled() -> None:
    loop = SlotLoop(PERIOD_NS, lambda slot_ns, now_ns: None)
    first, first_peer = socket.socketpair()
    seen: list[str] = []
    number = first.fileno()
    loop.watch(number, lambda: drain(first, seen, "first"))
    first.close()  # closed first: it leaves the epoll set by itself
    loop.unwatch(number)  # does not raise
    second, second_peer = socket.socketpair()
    reused = second if second.fileno() == number else None
    assert reused is not None, "the OS gives the lowest free number back"
    loop.watch(number, lambda: drain(second, seen, "second"))
    second_peer.send(b"x")
    run_slots(loop, 3)
    assert seen == ["second"]
    for sock in (first_peer, second, second_peer):
        sock.close()


def test_a_handler_that_closes_another_watched_descriptor_does_not_break_the_slot() -> None:
    loop = SlotLoop(PERIOD_NS, lambda slot_ns, now_ns: None)
    (a, a_peer), (b, b_peer) = socket.socketpair(), socket.socketpair()
    seen: list[str] = []

    def close_b() -> None:
        drain(a, seen, "a")
        loop.unwatch(b.fileno())
        b.close()

    loop.watch(a.fileno(), close_b)
    loop.watch(b.fileno(), lambda: drain(b, seen, "b"))
    a_peer.send(b"x")
    b_peer.send(b"y")  # both ready in the same slot
    run_slots(loop, 3)  # b's readiness, reported with a's, is not served once a closed it
    assert seen in (["a"], ["b", "a"])
    for sock in (a, a_peer, b_peer):
        sock.close()
