"""How a session drives an AUBO controller running ARCS: where it is, who logs in, and the
servo stream's rate, look-ahead and gain, each checked against AUBO's documented range.

The password never appears on a command line, in a recording or in a log: it is read from a
file or from the environment (:func:`password_from`), and :class:`ArcsSettings` keeps it out
of its ``repr``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

from hilrig.errors import ParameterError

RPC_PORT = 30004  # ARCS's JSON-RPC port on a real controller
RTDE_PORT = 30010  # ARCS's RTDE port
PASSWORD_ENV = "HILRIG_AUBO_PASSWORD"
DEFAULT_USER = "aubo"
EMULATED_PASSWORD = "123456"  # the emulated controller's (and a new controller's) password

# AUBO's documented ranges (motion_control.h, servoJoint): look-ahead 0.03-0.2 s, gain 100-2000;
# the servo stream runs at most at the controller's own cycle (500 Hz on the i-series)
SERVO_RATE_HZ = (1.0, 500.0)
LOOKAHEAD_S = (0.03, 0.2)
GAIN = (100.0, 2000.0)
RTDE_RATE_HZ = (1.0, 500.0)


@dataclass(frozen=True)
class ArcsSettings:
    """An ARCS controller and the servo stream a session sends it.

    ``servo_rate_hz``: ``servoJoint`` calls per second (each with ``t`` = one period);
    ``lookahead_s`` and ``gain``: the controller's smoothing of the streamed points;
    ``rtde_rate_hz``: the joint-state subscription's rate.
    """

    host: str = "127.0.0.1"
    rpc_port: int = RPC_PORT
    rtde_port: int = RTDE_PORT
    user: str = DEFAULT_USER
    password: str = field(default=EMULATED_PASSWORD, repr=False)
    servo_rate_hz: float = 200.0
    lookahead_s: float = 0.05
    gain: float = 200.0
    rtde_rate_hz: float = 500.0

    def __post_init__(self) -> None:
        for name, (low, high), unit in (
            ("servo rate", SERVO_RATE_HZ, "Hz"),
            ("servo look-ahead", LOOKAHEAD_S, "s"),
            ("servo gain", GAIN, ""),
            ("RTDE rate", RTDE_RATE_HZ, "Hz"),
        ):
            value = getattr(self, _FIELD[name])
            if not (
                isinstance(value, int | float) and math.isfinite(value) and low <= value <= high
            ):
                raise ParameterError(
                    f"{name} {value}{' ' + unit if unit else ''}: must be within "
                    f"{low:g}..{high:g}{' ' + unit if unit else ''} (AUBO's documented range)"
                )
        for name in ("rpc_port", "rtde_port"):
            port = getattr(self, name)
            if not (isinstance(port, int) and 0 < port < 65536):
                raise ParameterError(f"{name.replace('_', ' ')} {port}: must be within 1..65535")
        if not self.host:
            raise ParameterError("ARCS controller: no host given")

    @property
    def servo_period_s(self) -> float:
        return 1.0 / self.servo_rate_hz

    @property
    def rtde_period_ns(self) -> int:
        return round(1e9 / self.rtde_rate_hz)

    def where(self) -> str:
        """``host`` with both ports, for messages."""
        return f"{self.host} (RPC {self.rpc_port}, RTDE {self.rtde_port})"


_FIELD = {
    "servo rate": "servo_rate_hz",
    "servo look-ahead": "lookahead_s",
    "servo gain": "gain",
    "RTDE rate": "rtde_rate_hz",
}


def password_from(path: Path | None) -> str:
    """The controller's password: the first line of ``path`` if given, else the environment's
    :data:`PASSWORD_ENV`; raises ParameterError naming where it looked."""
    if path is not None:
        try:
            lines = path.read_text(encoding="utf-8").splitlines()
        except OSError as err:
            raise ParameterError(f"password file {path}: {err.strerror or err}") from None
        if not lines or not lines[0]:
            raise ParameterError(f"password file {path}: its first line is empty")
        return lines[0]
    value = os.environ.get(PASSWORD_ENV, "")
    if not value:
        raise ParameterError(
            f"no password for the AUBO controller: give --robot-password-file or set {PASSWORD_ENV}"
        )
    return value
