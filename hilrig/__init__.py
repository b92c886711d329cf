"""hilrig: hardware-in-the-loop experiments on collaborative-robot collision response.

``__version__`` is looked up in the installed metadata on first use (``importlib.metadata``
costs about 30 ms, which ``hilrig --help`` need not pay).
"""

__all__ = ["__version__"]


def __getattr__(name: str) -> str:
    """The installed version, read once when first asked for."""
    if name != "__version__":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from importlib.metadata import PackageNotFoundError, version

    try:
        found = version("hilrig")
    except PackageNotFoundError:  # running from a source tree that was never installed
        found = "0+unknown"
    globals()["__version__"] = found
    return found
