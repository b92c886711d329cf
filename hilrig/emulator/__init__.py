"""The emulated rig: device emulators speaking the real wire protocols over a pty and loopback.

It stands for the hardware, so it sits above the drivers (whose wire formats it speaks) and
below the rig (which starts it in a process of its own, :class:`~hilrig.emulator.rig.EmulatedRig`).

:class:`FtEmulator` is the Kunwei F/T sensor on a pseudo-terminal (noise, bias, tool gravity and
injectable faults); run it in a thread or as ``python -m hilrig.emulator.ft_emulator``.
"""

from hilrig.emulator.ft_emulator import EmulatorConfig, EmulatorStats, FtEmulator

__all__ = ["EmulatorConfig", "EmulatorStats", "FtEmulator"]
