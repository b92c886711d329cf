"""The emulated rig: device emulators speaking the real wire protocols over a pty and loopback.

:class:`FtEmulator` is the Kunwei F/T sensor on a pseudo-terminal (noise, bias, tool gravity and
injectable faults); run it in a thread or as ``python -m hilrig.drivers.emulated.ft_emulator``.
"""

from hilrig.drivers.emulated.ft_emulator import EmulatorConfig, EmulatorStats, FtEmulator

__all__ = ["EmulatorConfig", "EmulatorStats", "FtEmulator"]
