"""hilrig: hardware-in-the-loop experiments on collaborative-robot collision response."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("hilrig")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0+unknown"

__all__ = ["__version__"]
