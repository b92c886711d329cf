"""The robot's response: how the arm's joints follow the targets the loop commands.

The model is the emulated plant's (:mod:`hilrig.world.plant`): per joint a critically damped
second-order servo at ``bandwidth_rad_s``, saturated at the velocity and acceleration limits and
kept inside the position limits, integrated in sub-steps of ``substep_s``; a target commanded at
``t`` acts from ``t + delay_s`` (the loop's sensor-to-command time plus the transport and the
controller's own cycle). :func:`track` plays recorded commands through it (compiled; the closed
loop's kernel advances the same servos with :func:`advance`).

:func:`fit_response` identifies the model from a recording's commanded and measured joints by
least squares: the delay on a grid of sub-steps, the bandwidth by ``scipy.optimize``'s bounded
scalar search for each (or the plant's known bandwidth, for an emulated rig, where only the
delay is unknown). The fit reports the RMS tracking error it leaves (rad).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize_scalar

from hilrig.compiled import njit
from hilrig.errors import ParameterError
from hilrig.robot.limits import JointLimits
from hilrig.world.plant import integrate, servo_limits

Vector = NDArray[np.float64]

SUBSTEP_S = 0.0005  # the emulated plant's
EMULATED_BANDWIDTH_RAD_S = 60.0  # the emulated plant's (JointServoPlant's default)
MAX_DELAY_SUBSTEPS = 16  # 8 ms at 0.5 ms: the grid the delay is fitted on
BANDWIDTH_RANGE_RAD_S = (1.0, 500.0)


@dataclass(frozen=True)
class ServoResponse:
    """A fitted (or known) joint response: bandwidth (rad/s), delay (s), sub-step (s), the RMS
    of measured minus modelled joints over the fit (rad) and where the figures came from."""

    bandwidth_rad_s: float
    delay_s: float
    substep_s: float = SUBSTEP_S
    rms_rad: float = 0.0
    source: str = "identified"


@njit(cache=True)
def advance(
    q: Vector,
    qd: Vector,
    qdd: Vector,
    target: Vector,
    clock_s: Vector,
    until_s: float,
    commands_t_s: Vector,
    commands_q: NDArray[np.float64],
    cursor: NDArray[np.int64],
    count: int,
    limits: NDArray[np.float64],
    wn: float,
    substep_s: float,
    delay_s: float,
) -> None:
    """Integrate the servos from ``clock_s[0]`` in whole sub-steps up to ``until_s``, each
    sub-step tracking the newest command ``i < count`` with ``commands_t_s[i] + delay_s`` at or
    before its start (``cursor[0]`` is the next command not yet taken; before the first, the
    servos hold ``target`` as given)."""
    while clock_s[0] + substep_s <= until_s + 1e-12:
        now = clock_s[0]
        while cursor[0] < count and commands_t_s[cursor[0]] + delay_s <= now + 1e-12:
            for j in range(target.shape[0]):
                target[j] = commands_q[cursor[0], j]
            cursor[0] += 1
        integrate(q, qd, qdd, target, False, limits, wn, substep_s, 1)
        clock_s[0] = now + substep_s


@njit(cache=True)
def track(
    commands_t_s: Vector,
    commands_q: NDArray[np.float64],
    measured_t_s: Vector,
    q0: Vector,
    limits: NDArray[np.float64],
    wn: float,
    substep_s: float,
    delay_s: float,
) -> NDArray[np.float64]:
    """The modelled joints (n, 6) at ``measured_t_s`` (ascending) from rest at ``q0`` at
    ``measured_t_s[0]``, following ``commands_q`` (m, 6) sent at ``commands_t_s``."""
    joints = q0.shape[0]
    q, qd, qdd = q0.copy(), np.zeros(joints), np.zeros(joints)
    target = q0.copy()
    clock = np.array([measured_t_s[0]])
    cursor = np.zeros(1, dtype=np.int64)
    out = np.empty((measured_t_s.shape[0], joints))
    count = commands_t_s.shape[0]
    for i in range(measured_t_s.shape[0]):
        advance(q, qd, qdd, target, clock, measured_t_s[i], commands_t_s, commands_q,
                cursor, count, limits, wn, substep_s, delay_s)  # fmt: skip
        out[i] = q
    return out


def fit_response(
    commands_t_s: Vector,
    commands_q: NDArray[np.float64],
    measured_t_s: Vector,
    measured_q: NDArray[np.float64],
    limits: JointLimits,
    *,
    bandwidth_rad_s: float | None = None,
    substep_s: float = SUBSTEP_S,
) -> ServoResponse:
    """The servo model that best explains ``measured_q`` (n, 6) at ``measured_t_s`` given the
    commands; ``bandwidth_rad_s`` known (an emulated plant's) leaves only the delay to fit.
    Raises ParameterError (one line) when there is too little to fit."""
    if len(commands_t_s) < 10 or len(measured_t_s) < 10:
        raise ParameterError(
            f"too few commanded ({len(commands_t_s)}) or measured ({len(measured_t_s)}) joint "
            "samples to identify the robot's response"
        )
    packed = servo_limits(limits)
    t_cmd = np.ascontiguousarray(commands_t_s, dtype=np.float64)
    q_cmd = np.ascontiguousarray(commands_q, dtype=np.float64)
    t_meas = np.ascontiguousarray(measured_t_s, dtype=np.float64)
    q_meas = np.asarray(measured_q, dtype=np.float64)
    q0 = np.ascontiguousarray(q_meas[0])

    def rms(wn: float, delay_s: float) -> float:
        modelled = track(t_cmd, q_cmd, t_meas, q0, packed, wn, substep_s, delay_s)
        return float(np.sqrt(np.mean((modelled - q_meas) ** 2)))

    best: tuple[float, float, float] | None = None
    for steps in range(MAX_DELAY_SUBSTEPS + 1):
        delay = steps * substep_s
        if bandwidth_rad_s is not None:
            wn, error = bandwidth_rad_s, rms(bandwidth_rad_s, delay)
        else:
            low, high = BANDWIDTH_RANGE_RAD_S
            found = minimize_scalar(
                lambda log_wn: rms(math.exp(log_wn), delay),  # noqa: B023 - called here
                bounds=(math.log(low), math.log(high)),
                method="bounded",
                options={"xatol": 1e-3},
            )
            wn, error = math.exp(float(found.x)), float(found.fun)
        if best is None or error < best[2]:
            best = (wn, delay, error)
    assert best is not None
    source = "emulated plant, delay identified" if bandwidth_rad_s is not None else "identified"
    return ServoResponse(best[0], best[1], substep_s, best[2], source)
