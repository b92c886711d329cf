"""Tare and tool gravity compensation of a wrist F/T sensor; tool load identification.

Frames and convention: a reading is the wrench the tool side applies to the sensor, in the
sensor frame S (N, N*m, torque about the sensor origin). A tool of mass ``m`` with its centre of
gravity ``c`` (in S, m) under gravity ``g`` (in the base frame B, m/s^2) adds::

    f_g = m * R_BS^T g        tau_g = c x f_g

where ``R_BS`` is the sensor orientation in the base frame (from forward kinematics and the
sensor mounting). A reading is ``w = bias + [f_g; tau_g] + w_ext``; compensation returns
``w_ext``. Pure numpy; :meth:`GravityCompensator.compensate` with ``out`` allocates nothing.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hilrig.errors import ParameterError

STANDARD_GRAVITY_IN_BASE = (0.0, 0.0, -9.80665)  # m/s^2, base z up


@dataclass(frozen=True, slots=True)
class ToolLoad:
    """What hangs on the sensor: mass (kg) and centre of gravity in the sensor frame (m)."""

    mass_kg: float = 0.0
    com_in_sensor_m: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if not self.mass_kg >= 0.0:
            raise ParameterError(f"ToolLoad.mass_kg must be >= 0, got {self.mass_kg}")

    def wrench_map(self) -> NDArray[np.float64]:
        """The (6, 3) matrix ``[m I; m [c]x]`` taking gravity in S (m/s^2) to the tool's wrench."""
        cx, cy, cz = self.com_in_sensor_m
        skew = np.array([[0.0, -cz, cy], [cz, 0.0, -cx], [-cy, cx, 0.0]])
        return self.mass_kg * np.vstack([np.eye(3), skew])


def gravity_wrench(
    load: ToolLoad,
    r_base_sensor: NDArray[np.float64],
    *,
    gravity_in_base: Sequence[float] = STANDARD_GRAVITY_IN_BASE,
) -> NDArray[np.float64]:
    """The tool's own wrench (6,) on the sensor in S (N, N*m) at orientation ``r_base_sensor``."""
    gravity_in_sensor = np.asarray(gravity_in_base, dtype=np.float64) @ r_base_sensor
    return load.wrench_map() @ gravity_in_sensor


class GravityCompensator:
    """Subtracts the bias and the tool's gravity wrench from raw readings, in the sensor frame."""

    def __init__(
        self,
        load: ToolLoad | None = None,
        *,
        gravity_in_base: Sequence[float] = STANDARD_GRAVITY_IN_BASE,
        bias_in_sensor: ArrayLike = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    ) -> None:
        self.load = ToolLoad() if load is None else load
        self._map = self.load.wrench_map()
        self._gravity_in_base = np.array(gravity_in_base, dtype=np.float64)
        self._bias = np.array(bias_in_sensor, dtype=np.float64)
        if self._bias.shape != (6,):
            raise ParameterError(f"bias_in_sensor must have 6 values, got shape {self._bias.shape}")
        self._gravity_in_sensor = np.empty(3)
        self._tool_wrench = np.empty(6)

    @property
    def bias_in_sensor(self) -> NDArray[np.float64]:
        """A copy of the current bias (6,), N and N*m."""
        return self._bias.copy()

    @property
    def gravity_in_base(self) -> NDArray[np.float64]:
        """A copy of gravity in the base frame (3,), m/s^2."""
        return self._gravity_in_base.copy()

    def tare(self, wrench_in_sensor: ArrayLike, r_base_sensor: NDArray[np.float64]) -> None:
        """Take ``wrench_in_sensor`` (mean raw reading, no contact) at ``r_base_sensor`` as zero.

        The bias becomes the reading minus the tool's gravity wrench at that orientation, so
        compensated readings stay zero when the arm then moves the tool around.
        """
        self._bias = np.asarray(wrench_in_sensor, dtype=np.float64) - self._tool(r_base_sensor)

    def compensate(
        self,
        wrench_in_sensor: ArrayLike,
        r_base_sensor: NDArray[np.float64],
        out: NDArray[np.float64] | None = None,
    ) -> NDArray[np.float64]:
        """External wrench (6,) in S: reading minus bias minus tool gravity at ``r_base_sensor``.

        With ``out`` (a float64 (6,) array) and an ndarray reading nothing is allocated.
        """
        if out is None:
            out = np.empty(6)
        np.subtract(wrench_in_sensor, self._bias, out=out)
        np.subtract(out, self._tool(r_base_sensor), out=out)
        return out

    def _tool(self, r_base_sensor: NDArray[np.float64]) -> NDArray[np.float64]:
        np.matmul(self._gravity_in_base, r_base_sensor, out=self._gravity_in_sensor)  # = R^T g
        return np.matmul(self._map, self._gravity_in_sensor, out=self._tool_wrench)


def identify_tool_load(
    wrenches_in_sensor: ArrayLike,
    r_base_sensor: ArrayLike,
    *,
    gravity_in_base: Sequence[float] = STANDARD_GRAVITY_IN_BASE,
) -> tuple[ToolLoad, NDArray[np.float64]]:
    """Tool load and sensor bias (6,) from contact-free readings at several orientations.

    ``wrenches_in_sensor`` is (N, 6) mean raw readings, ``r_base_sensor`` (N, 3, 3) the sensor
    orientations; least squares on ``f = b_f + m R^T g`` and ``tau = b_tau + (m c) x R^T g``.
    Needs at least three orientations that are not all about one axis; raises
    :class:`~hilrig.errors.ParameterError` if the poses cannot determine the load.
    """
    wrenches = np.asarray(wrenches_in_sensor, dtype=np.float64)
    rotations = np.asarray(r_base_sensor, dtype=np.float64)
    count = wrenches.shape[0]
    if wrenches.shape != (count, 6) or rotations.shape != (count, 3, 3) or count < 3:
        raise ParameterError(
            f"identify_tool_load: need (N, 6) wrenches and (N, 3, 3) rotations with N >= 3, "
            f"got {wrenches.shape} and {rotations.shape}"
        )
    gravity = np.einsum("j,njk->nk", np.asarray(gravity_in_base, dtype=np.float64), rotations)
    eye = np.broadcast_to(np.eye(3), (count, 3, 3))
    force_rows = np.concatenate([eye, gravity[:, :, None]], axis=2).reshape(-1, 4)
    skew = np.zeros((count, 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -gravity[:, 2], gravity[:, 1], -gravity[:, 0]
    skew -= skew.transpose(0, 2, 1)
    torque_rows = np.concatenate([eye, -skew], axis=2).reshape(-1, 6)  # (mc) x g = -[g]x (mc)
    if np.linalg.matrix_rank(torque_rows) < 6:
        raise ParameterError("identify_tool_load: orientations too alike to separate bias and load")
    force_fit = np.linalg.lstsq(force_rows, wrenches[:, :3].reshape(-1), rcond=None)[0]
    torque_fit = np.linalg.lstsq(torque_rows, wrenches[:, 3:].reshape(-1), rcond=None)[0]
    mass_kg = float(force_fit[3])
    if mass_kg <= 0.0:
        raise ParameterError(f"identify_tool_load: fitted mass {mass_kg:.4g} kg is not positive")
    cx, cy, cz = (float(v) for v in torque_fit[3:] / mass_kg)
    bias = np.concatenate([force_fit[:3], torque_fit[:3]])
    return ToolLoad(mass_kg, (cx, cy, cz)), bias
