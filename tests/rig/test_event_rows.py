"""Events cross to the recorder as fixed-size rows: every field comes back as it was put, a text
too long for its field is cut at a character's end and marked, and putting one starts no thread
in the loop's process."""

from __future__ import annotations

import threading
from dataclasses import astuple

from hypothesis import given
from hypothesis import strategies as st

from hilrig.recording import EventKind, EventRecord
from hilrig.rig import RecorderFeed
from hilrig.rig.records import CUT, DETAIL_BYTES, fitted
from hilrig.rig.row_messages import EVENTS_TOPIC, event_samples


@given(st.text(max_size=300), st.integers(min_value=len(CUT) + 4, max_value=200))
def test_a_fitted_text_is_whole_or_a_marked_prefix_within_its_size(text: str, size: int) -> None:
    data = fitted(text, size)
    assert len(data) <= size
    kept = data.decode()  # never a broken character
    if len(text.encode()) <= size:
        assert kept == text
    else:
        assert data.endswith(CUT)
        head = kept[: -len(CUT)]
        assert text.startswith(head)
        # cut no shorter than the room allows: the next character would not have fitted
        assert len(head.encode()) + len(text[len(head)].encode()) > size - len(CUT)


def test_events_come_back_from_their_ring_as_they_were_put() -> None:
    long = "é" * DETAIL_BYTES  # two bytes each: twice the field
    records = [
        EventRecord(5, EventKind.COLLISION_START, "controller", "", "end effector"),
        EventRecord(7, EventKind.FAULT, "safety", "protective limit: robot stopped", value=151.5),
        EventRecord(9, EventKind.OPERATOR_MARK, "virtual collision", "playback started"),
        EventRecord(11, EventKind.FAULT, "joint targets", long, value=-0.0),
    ]
    threads = threading.active_count()
    with RecorderFeed(rows=4, events=8) as feed:
        assert all(feed.event(record) for record in records)
        assert threading.active_count() == threads  # no feeder thread, unlike a queue's
        messages = list(event_samples(feed.events.read_available()))
        assert len(feed.events.read_available()) == 0  # read once: the slots were released
    assert {topic for topic, _ in messages} == {EVENTS_TOPIC}
    back = [record for _, record in messages]
    assert [key(r) for r in back[:3]] == [key(r) for r in records[:3]]
    cut = "é" * ((DETAIL_BYTES - len(CUT)) // 2) + CUT.decode()
    assert key(back[3]) == key(EventRecord(11, EventKind.FAULT, "joint targets", cut, value=-0.0))


def test_a_full_event_ring_refuses_and_counts_each_event() -> None:
    with RecorderFeed(rows=4, events=2) as feed:
        put = [feed.event(EventRecord(k, EventKind.FAULT, "test")) for k in range(5)]
        assert put == [True, True, False, False, False]
        assert (feed.events.dropped, feed.drops) == (3, 3)


def key(record: EventRecord) -> tuple[object, ...]:
    """An event's fields, its value by repr (NaN equals NaN, -0.0 differs from 0.0)."""
    return (*astuple(record)[:-1], repr(record.value))
