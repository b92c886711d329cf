"""The study file, ``DIR/study.toml``: the study's name, its baseline and its exclusions.

It sits beside the data, is meant to be read, diffed and committed with the analysis, and is
the only thing curation changes: recordings are never modified. Format (docs/study.md)::

    [study]
    name = "hand-contact pilot"     # optional; default: the folder's name
    baseline = "fixed"              # optional; default: fixed, else the first condition

    [[exclude]]
    session = "20261202-101500-S003"
    reason = "the subject stepped back before contact"

    [[exclude]]
    session = "20261202-102000-S004"
    event = 2                       # one event of the session (0, 1, ...), not all of it
    reason = "the operator touched the sensor"

Reasons are free text kept in the study: they must not name or describe a person beyond the
study's pseudonyms.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import tomli_w

from hilrig.errors import StudyError
from hilrig.outputs import new_files
from hilrig.study.records import Exclusion

STUDY_FILE = "study.toml"
HEADER = (
    "# hilrig study file (docs/study.md): the study's name, baseline and exclusions.\n"
    "# Edited by `hilrig study exclude/include`; recordings are never modified.\n\n"
)


@dataclass(frozen=True)
class StudyFile:
    """The study file's contents (all optional)."""

    name: str = ""
    baseline: str = ""
    exclusions: tuple[Exclusion, ...] = ()


def read_study(root: Path) -> StudyFile:
    """``root/study.toml``; an empty StudyFile without one. StudyError (one line naming the
    file and what is wrong) for a file that is not valid."""
    path = root / STUDY_FILE
    if not path.exists():
        return StudyFile()
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as err:
        raise StudyError(f"{path}: cannot read it ({err})") from err
    except tomllib.TOMLDecodeError as err:
        raise StudyError(f"{path}: not valid TOML ({err})") from err
    _only(path, "the file", data, ("study", "exclude"))
    head = data.get("study", {})
    if not isinstance(head, Mapping):
        raise StudyError(f"{path}: [study] must be a table")
    _only(path, "[study]", head, ("name", "baseline"))
    name = _text(path, "[study]", head, "name", required=False)
    baseline = _text(path, "[study]", head, "baseline", required=False)
    entries = data.get("exclude", [])
    if not isinstance(entries, list):
        raise StudyError(f"{path}: exclude must be an array of tables ([[exclude]])")
    return StudyFile(name, baseline, tuple(_exclusion(path, i, e) for i, e in enumerate(entries)))


def _exclusion(path: Path, number: int, entry: object) -> Exclusion:
    where = f"[[exclude]] number {number + 1}"
    if not isinstance(entry, Mapping):
        raise StudyError(f"{path}: {where} must be a table")
    _only(path, where, entry, ("session", "event", "reason"))
    event = entry.get("event")
    if event is not None and (isinstance(event, bool) or not isinstance(event, int) or event < 0):
        raise StudyError(f"{path}: {where}: event must be an event number >= 0, got {event!r}")
    session = _text(path, where, entry, "session", required=True)
    return Exclusion(session, _text(path, where, entry, "reason", required=True), event)


def _only(path: Path, where: str, table: Mapping[str, object], keys: Sequence[str]) -> None:
    unknown = [k for k in table if k not in keys]
    if unknown:
        raise StudyError(f"{path}: {where} has no key {unknown[0]!r}; its keys: {', '.join(keys)}")


def _text(path: Path, where: str, table: Mapping[str, object], key: str, *, required: bool) -> str:
    value = table.get(key, "")
    if not isinstance(value, str) or "\n" in value or (required and not value.strip()):
        raise StudyError(f"{path}: {where}: {key} must be one line of text, got {value!r}")
    return value.strip()


def write_study(root: Path, study: StudyFile) -> Path:
    """Write ``root/study.toml`` (replacing it at once, never half-written)."""
    document: dict[str, object] = {}
    head = {k: v for k, v in (("name", study.name), ("baseline", study.baseline)) if v}
    if head:
        document["study"] = head
    if study.exclusions:
        document["exclude"] = [
            {"session": e.session}
            | ({} if e.event is None else {"event": e.event})
            | {"reason": e.reason}
            for e in study.exclusions
        ]
    path = root / STUDY_FILE
    with new_files(path, overwrite=True) as (tmp,):
        tmp.write_text(HEADER + tomli_w.dumps(document), encoding="utf-8")
    return path


def exclude(study: StudyFile, session: str, reason: str, events: Sequence[int] = ()) -> StudyFile:
    """``study`` with ``session`` (or only its ``events``) excluded for ``reason``; an
    exclusion already there gets the new reason."""
    if not reason.strip() or "\n" in reason:
        raise StudyError(f"the reason must be one line of text, got {reason!r}")
    if any(e < 0 for e in events):
        raise StudyError(f"event numbers start at 0, got {min(events)}")
    targets: list[int | None] = list(dict.fromkeys(events)) or [None]
    replaced = {(session, t) for t in targets}
    kept = [e for e in study.exclusions if (e.session, e.event) not in replaced]
    added = [Exclusion(session, reason.strip(), t) for t in targets]
    return replace(study, exclusions=(*kept, *added))


def include(study: StudyFile, session: str, events: Sequence[int] = ()) -> StudyFile:
    """``study`` without the exclusions of ``session`` (all, or those of ``events``);
    StudyError when there is none to remove."""
    wanted = set(events)
    kept = tuple(
        e for e in study.exclusions if e.session != session or (wanted and e.event not in wanted)
    )
    if len(kept) == len(study.exclusions):
        what = session if not events else f"{session} events {sorted(wanted)}"
        raise StudyError(f"{what} is not excluded in {STUDY_FILE}")
    return replace(study, exclusions=kept)
