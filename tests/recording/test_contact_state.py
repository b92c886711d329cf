"""One ContactState, codes 0..3: the recording's enum is the controller's, the controller
emits its codes and the ControllerState message definition declares the same ones."""

from __future__ import annotations

import re

import numpy as np

from hilrig.control import ContactState as ControlContactState
from hilrig.control import simulate
from hilrig.recording import ContactState, MessageType
from hilrig.recording.msgdef import packaged_message


def test_the_codes_are_free_contact_holding_recovering() -> None:
    assert [(s.name, int(s)) for s in ContactState] == [
        ("FREE", 0),
        ("CONTACT", 1),
        ("HOLDING", 2),
        ("RECOVERING", 3),
    ]


def test_the_controller_uses_the_recordings_enum_and_codes() -> None:
    assert ControlContactState is ContactState
    force = np.zeros(5000)
    force[10:600] = 3.0  # contact, holding after 0.5 s, released, recovering, free again
    contact = simulate("adaptive", force, 0.001, "adaptive").contact[:, 0]
    visited = contact[np.flatnonzero(np.diff(contact, prepend=-1))]
    names = [ContactState(code).name for code in visited]
    assert names == ["FREE", "CONTACT", "HOLDING", "RECOVERING", "FREE"]


def test_the_message_definition_declares_the_same_codes() -> None:
    text = packaged_message(MessageType.CONTROLLER_STATE.value).text
    declared = dict(re.findall(r"^int8 ([A-Z]+)=(\d+)$", text, flags=re.MULTILINE))
    assert declared == {s.name: str(int(s)) for s in ContactState}
