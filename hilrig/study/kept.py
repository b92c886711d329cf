"""What a study keeps beside its data (``DIR/.hilrig-study/``): Parquet tables stamped with the
key of what they were computed from, read back only while that key still holds."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from hilrig.outputs import new_files

KEY = "hilrig.key"


def read_kept(path: Path, key: str, columns: Sequence[str]) -> pd.DataFrame | None:
    """The table kept at ``path``; None when there is none, it cannot be read, or its key or
    columns are not these (it is then computed again)."""
    if not path.is_file():
        return None
    try:
        table = pd.read_parquet(path)
    except (OSError, ValueError):
        return None
    if table.attrs.get(KEY) != key or list(table.columns) != list(columns):
        return None
    return table


def keep(path: Path, table: pd.DataFrame, key: str) -> None:
    """Write ``table`` to ``path`` stamped with ``key``, replacing what was there (all or nothing:
    :func:`hilrig.outputs.new_files`); OSError or OutputError when it cannot be written."""
    frame = table.copy()
    frame.attrs[KEY] = key
    with new_files(path, overwrite=True, create_folders=True) as (tmp,):
        frame.to_parquet(tmp, index=False)
