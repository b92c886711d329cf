"""The one exception hierarchy of hilrig, by category (control, parameters, input data).

Every error hilrig raises on purpose derives from :class:`HilrigError`, so a caller (the CLI, a
test, the real-time loop) can tell an expected, explained failure from a bug.
"""


class HilrigError(Exception):
    """Base of every error hilrig raises on purpose; its message is one line: what and where."""


class StoppedWaitingError(HilrigError):
    """A session stopped (Ctrl-C, SIGTERM) while it waited for the machine's other session:
    nothing was recorded. The command line reports it as an interrupt (exit 130)."""


class ControlError(HilrigError):
    """A controller cannot run as asked."""


class ParameterError(ControlError, ValueError):
    """Parameters that are invalid or cannot be stable, refused before any motion."""


class NonFiniteForceError(ControlError, ValueError):
    """A force/torque input was NaN or infinite; it is refused, never integrated."""


class RecordingError(HilrigError):
    """An MCAP session cannot be written or read as asked; the message names the file and why."""


class DriverError(HilrigError):
    """A device driver failed; the message names the device, endpoint and what happened."""


class LinkError(DriverError):
    """A device link (serial port, socket) could not be opened or was lost."""


class ProtocolError(DriverError):
    """Bytes on a device link (either way) that do not follow the device's protocol."""


class ModbusExceptionError(DriverError):
    """The Modbus device answered a request with an exception code."""

    def __init__(self, code: int, name: str, request: str) -> None:
        super().__init__(f"Modbus exception {code} ({name}) in reply to {request}")
        self.code = code
        self.code_name = name


class RobotModelError(HilrigError, ValueError):
    """A robot model cannot be built or was called with inputs of the wrong shape."""


class AnalysisError(HilrigError):
    """Sessions or replay results cannot be analysed as asked; the message names what and why."""


class ReplayError(HilrigError):
    """An offline replay cannot run as asked: unusable input, bad controller spec or output."""


class ViewError(HilrigError):
    """A view cannot be built or shown: unusable input, bad display options, no viewer."""


class OutputError(HilrigError):
    """An output cannot be written as asked: it exists, or its folder is missing or read-only."""


class DiskError(OutputError):
    """An output could not be written because its disk is full, over quota, past its largest
    file or failing (ENOSPC, EDQUOT, EFBIG, EIO); the message says what is kept and what to do."""


class StudyError(HilrigError):
    """A study cannot be indexed, curated or reported as asked (bad folder, study file, filter)."""


class SweepError(HilrigError):
    """A parameter sweep cannot run as asked: bad sources, output folder, engine or cluster."""
