"""Events from per-tick states: emitted on changes only, clamp flags named in words."""

from hilrig.recording.samples import EventKind, EventRecord
from hilrig.rig.events import EventDetector, clamp_names
from hilrig.tick.clamp_kernels import Clamp


def test_every_clamp_flag_has_its_words_in_bit_order() -> None:
    assert clamp_names(int(Clamp.VELOCITY | Clamp.ACCELERATION)) == (
        "velocity limit, acceleration limit"
    )
    assert clamp_names(int(Clamp.HOLDING)) == "controlled stop"
    every = [clamp_names(int(flag)) for flag in Clamp]
    assert every == [
        "position limit",
        "velocity limit",
        "acceleration limit",
        "workspace box",
        "non-finite target",
        "controlled stop",
    ]
    assert clamp_names(0) == ""


def test_clamp_events_name_the_flags_once_per_change() -> None:
    events: list[EventRecord] = []
    detector = EventDetector(on_event=events.append)
    for t_ns, flags in enumerate([0, 32, 32, 32, 0, 2 | 4, 2 | 4, 0]):
        detector.clamp(flags, t_ns)
    limited = " (the commanded motion was limited to stay safe)"
    assert [(e.t_ns, e.kind, e.source, e.detail) for e in events] == [
        (1, EventKind.FAULT, "safety", f"clamp engaged: controlled stop{limited}"),
        (
            5,
            EventKind.FAULT,
            "safety",
            f"clamp engaged: velocity limit, acceleration limit{limited}",
        ),
    ]


def test_a_stale_link_says_the_robot_holds_its_pose_and_when_it_resumes() -> None:
    events: list[EventRecord] = []
    detector = EventDetector(on_event=events.append)
    for t_ns, ok in enumerate([True, False, False, True, True]):
        detector.link("wrist F/T sensor", ok, t_ns)
    assert [(e.t_ns, e.source, e.detail) for e in events] == [
        (
            1,
            "wrist F/T sensor",
            "stale or lost: the robot holds its pose until the data is fresh again",
        ),
        (3, "wrist F/T sensor", "data fresh again: tracking resumes"),
    ]
