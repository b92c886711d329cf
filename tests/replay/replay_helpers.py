"""Inputs for the replay tests: the example recording and small sessions written inline."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hilrig.control import combine, preset, simulate
from hilrig.recording import (
    ControllerSample,
    JointSample,
    SessionInfo,
    SessionWriter,
    WrenchSample,
    default_channels,
)
from hilrig.replay import ForceTrace

EXAMPLE = Path(__file__).parents[2] / "recordings" / "example-paper-end-effector.mcap"
AXES = ("x", "y", "z", "joint1", "joint2", "joint3", "joint4", "joint5", "joint6")
START_MONO_NS = 7_000_000_000
CHANNELS = {c.topic: c for c in default_channels()}
#: A stiff hand pushing along base x: 20 mm past the tool at 0.1 m/s, held 1 s, once
#: (``hand-contact``'s settings), and a session long enough for it and the return.
HAND = {"direction_in_base": "1,0,0", "stiffness_n_m": 800, "depth_m": 0.02, "period_s": None}
HAND_SECONDS = 2.0 + 2 * (0.05 + 0.02) / 0.1 + 1.0 + 0.6


def session_info(params: Mapping[str, object] | None = None) -> SessionInfo:
    return SessionInfo(
        session_id="replay-test",
        subject_id="S003",
        rig="emulated",
        controller="adaptive",
        start_utc_ns=1_767_225_600_000_000_000,
        start_monotonic_ns=START_MONO_NS,
        controller_params=dict(params or {}),  # type: ignore[arg-type]
    )


def collision(ticks: int, dt_s: float, axes: int = 9, seed: int = 0) -> NDArray[np.float64]:
    """Noise plus a 1 s push of 8 N (N*m) starting at a third of the trace, on every axis."""
    rng = np.random.default_rng(seed)
    t = np.arange(ticks) * dt_s
    onset = ticks * dt_s / 3
    push = np.where((t >= onset) & (t < onset + 1.0), 8.0 * np.sin(np.pi * (t - onset)), 0.0)
    return push[:, None] * np.linspace(1.0, 0.5, axes) + rng.normal(0.0, 0.05, (ticks, axes))


def trace(ticks: int = 3000, dt_s: float = 0.002, axes: tuple[str, ...] = AXES) -> ForceTrace:
    force = collision(ticks, dt_s, len(axes))
    return ForceTrace(np.arange(ticks) * dt_s, force, axes, "inline", dt_s)


def write_state_session(
    path: Path,
    force: NDArray[np.float64],
    *,
    rate_hz: float = 1000.0,
    params: Mapping[str, object] | None = None,
    law: str = "adaptive",
) -> Path:
    """A session whose /controller/state is the loop's default controller over ``force``
    (T, 9), metadata ``params`` (default: just law and rate_hz)."""
    dt = 1.0 / rate_hz
    combined = combine((preset("adaptive"), 3), (preset("adaptive-joint"), 6))
    result = simulate(law, force, dt, combined)
    m = combined.per_axis("m", 9)
    zeta = result.damping / (2.0 * np.sqrt(m * result.stiffness))
    record = {"law": law, "rate_hz": rate_hz} if params is None else params
    spec = CHANNELS["/controller/state"]
    with SessionWriter(path, session_info(record), channels=[spec]) as writer:
        for n in range(force.shape[0]):
            f = force[n].tolist()
            writer.write(
                spec.topic,
                ControllerSample(
                    START_MONO_NS + round(n * dt * 1e9),
                    f,
                    result.offset[n].tolist(),
                    result.velocity[n].tolist(),
                    result.damping[n].tolist(),
                    result.stiffness[n].tolist(),
                    np.tanh(force[n] ** 2).tolist(),
                    zeta[n].tolist(),
                    result.contact[n].tolist(),
                ),
            )
    return path


def write_input_session(
    path: Path,
    wrench: NDArray[np.float64],
    torque: NDArray[np.float64] | None,
    *,
    period_ns: int = 1_000_000,
    joint_lead_ns: int = 300_000,
) -> Path:
    """A session with /controller/input (wrench (T, 3)) and, if given, /joint_states whose
    efforts are ``torque`` (T, 6), each frame ``joint_lead_ns`` before its tick."""
    channels = [CHANNELS["/controller/input"]]
    if torque is not None:
        channels.append(CHANNELS["/joint_states"])
    info = session_info({"law": "adaptive", "rate_hz": 1e9 / period_ns})
    with SessionWriter(path, info, channels=channels) as writer:
        for n in range(wrench.shape[0]):
            t = START_MONO_NS + n * period_ns
            if torque is not None:
                q = [0.0] * 6
                tau = torque[n].tolist()
                sample = JointSample(t - joint_lead_ns, q, q, tau, device_t_ns=n, device_seq=n)
                writer.write("/joint_states", sample)
            f = wrench[n].tolist()
            writer.write("/controller/input", WrenchSample(t, (f[0], f[1], f[2]), (0.0, 0.0, 0.0)))
    return path


def tampered_copy(tmp_path: Path) -> Path:
    """The example recording, its metadata claiming a1 = 30 where the loop ran a1 = 20."""
    data = EXAMPLE.read_bytes()
    claimed = b'"a1": "(20.0, 20.0, 20.0, 6.0'
    assert data.count(claimed) == 1
    path = tmp_path / "tampered.mcap"
    path.write_bytes(data.replace(claimed, b'"a1": "(30.0, 30.0, 30.0, 6.0'))
    return path
