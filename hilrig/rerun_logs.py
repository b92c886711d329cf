"""Rerun's own log lines kept off the terminal.

Rerun's SDK reads ``RUST_LOG`` once, when it is imported, so this is set around its import and
around the spawn of a process that imports it. What goes wrong reaches hilrig as an error,
which it says once, where Rerun would log it too (a viewer that went away: two lines, colours
and all). A ``RUST_LOG`` the user set is left as it is.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def rerun_logs_off() -> Iterator[None]:
    """``RUST_LOG=off`` within the block, unless ``RUST_LOG`` is set already."""
    if "RUST_LOG" in os.environ:
        yield
        return
    os.environ["RUST_LOG"] = "off"
    try:
        yield
    finally:
        os.environ.pop("RUST_LOG", None)  # what Rerun started meanwhile keeps its setting
