"""One ContactState, codes 0..3: the recording's enum is the controller's, and the compiled
kernel and the ControllerState message definition use the same codes."""

from __future__ import annotations

import re

from hilrig.control import ContactState as ControlContactState
from hilrig.control import kernel
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
    kernel_codes = (kernel.FREE, kernel.CONTACT, kernel.HOLDING, kernel.RECOVERING)
    assert kernel_codes == tuple(int(s) for s in ContactState)


def test_the_message_definition_declares_the_same_codes() -> None:
    text = packaged_message(MessageType.CONTROLLER_STATE.value).text
    declared = dict(re.findall(r"^int8 ([A-Z]+)=(\d+)$", text, flags=re.MULTILINE))
    assert declared == {s.name: str(int(s)) for s in ContactState}
