"""The one exception hierarchy of hilrig, by category (control, parameters, input data).

Every error hilrig raises on purpose derives from :class:`HilrigError`, so a caller (the CLI, a
test, the real-time loop) can tell an expected, explained failure from a bug.
"""


class HilrigError(Exception):
    """Base of every error hilrig raises on purpose; its message is one line: what and where."""


class ControlError(HilrigError):
    """A controller cannot run as asked."""


class ParameterError(ControlError, ValueError):
    """Parameters that are invalid or cannot be stable, refused before any motion."""


class NonFiniteForceError(ControlError, ValueError):
    """A force/torque input was NaN or infinite; it is refused, never integrated."""
