"""The machine under the loop: its settings that bear on a 1 kHz loop (:func:`read_settings`,
and a sensor's serial port's: :func:`port_settings`) and its measured timing floor
(:func:`measure_floor`), as ``hilrig doctor`` reports them."""

from hilrig.machine.floor import Floor, Steal, Timing, WakeUps, measure_floor, timing
from hilrig.machine.serial_port import port_settings
from hilrig.machine.settings import Setting, read_settings

__all__ = [
    "Floor",
    "Setting",
    "Steal",
    "Timing",
    "WakeUps",
    "measure_floor",
    "port_settings",
    "read_settings",
    "timing",
]
