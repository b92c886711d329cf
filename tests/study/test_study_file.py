"""The study file: exclusions kept beside the data, human-readable, every mistake one line."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from hilrig.errors import StudyError
from hilrig.study.records import Exclusion
from hilrig.study.study_file import StudyFile, exclude, include, read_study, write_study


def test_no_file_is_an_empty_study(tmp_path: Path) -> None:
    assert read_study(tmp_path) == StudyFile()


def test_exclusions_round_trip_through_readable_toml(tmp_path: Path) -> None:
    study = exclude(StudyFile(name="pilot", baseline="fixed"), "S1-a", "stepped back")
    study = exclude(study, "S2-b", "operator touched the sensor", [2, 0])
    written = write_study(tmp_path, study)
    text = written.read_text(encoding="utf-8")
    assert text.startswith("# hilrig study file")
    assert tomllib.loads(text) == {
        "study": {"name": "pilot", "baseline": "fixed"},
        "exclude": [
            {"session": "S1-a", "reason": "stepped back"},
            {"session": "S2-b", "event": 2, "reason": "operator touched the sensor"},
            {"session": "S2-b", "event": 0, "reason": "operator touched the sensor"},
        ],
    }
    assert read_study(tmp_path) == study
    assert [e.target for e in study.exclusions] == ["S1-a", "S2-b#2", "S2-b#0"]


def test_excluding_again_replaces_the_reason_and_include_takes_it_back() -> None:
    study = exclude(StudyFile(), "S1-a", "first reason")
    study = exclude(study, "S1-a", "second reason")
    assert study.exclusions == (Exclusion("S1-a", "second reason"),)
    study = exclude(study, "S1-a", "one event", [3])
    assert include(study, "S1-a", [3]).exclusions == (Exclusion("S1-a", "second reason"),)
    assert include(study, "S1-a").exclusions == ()
    with pytest.raises(StudyError, match=r"^S9 is not excluded in study\.toml$"):
        include(study, "S9")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[study\n", "not valid TOML"),
        ("colour = 1\n", "the file has no key 'colour'; its keys: study, exclude"),
        ("[study]\nowner = 'x'\n", "[study] has no key 'owner'; its keys: name, baseline"),
        ("exclude = 3\n", "exclude must be an array of tables ([[exclude]])"),
        ("[[exclude]]\nsession = 'S1'\n", "[[exclude]] number 1: reason must be one line of text"),
        (
            "[[exclude]]\nsession = 'S1'\nreason = 'r'\nevent = -1\n",
            "[[exclude]] number 1: event must be an event number >= 0, got -1",
        ),
        (
            "[[exclude]]\nsession = 'S1'\nreason = 'r'\nwhy = 'x'\n",
            "[[exclude]] number 1 has no key 'why'; its keys: session, event, reason",
        ),
    ],
)
def test_a_bad_study_file_is_one_line_naming_it(tmp_path: Path, text: str, message: str) -> None:
    (tmp_path / "study.toml").write_text(text, encoding="utf-8")
    with pytest.raises(StudyError) as caught:
        read_study(tmp_path)
    assert str(caught.value).startswith(f"{tmp_path / 'study.toml'}: ")
    assert message in str(caught.value) and "\n" not in str(caught.value)


def test_a_reason_must_be_one_line() -> None:
    with pytest.raises(StudyError, match=re.escape("the reason must be one line of text, got ''")):
        exclude(StudyFile(), "S1", "")
    with pytest.raises(StudyError, match="event numbers start at 0, got -2"):
        exclude(StudyFile(), "S1", "r", [-2])


texts = st.text(
    alphabet=st.characters(blacklist_categories=("Cs", "Cc")), min_size=1, max_size=30
).filter(lambda s: s.strip() == s and s)


@given(
    st.lists(
        st.tuples(texts, texts, st.none() | st.integers(0, 50)),
        max_size=6,
        unique_by=lambda t: (t[0], t[2]),
    )
)
def test_any_exclusions_survive_writing_and_reading(
    tmp_path_factory: pytest.TempPathFactory, entries: list[tuple[str, str, int | None]]
) -> None:
    root = tmp_path_factory.mktemp("study")
    study = StudyFile(exclusions=tuple(Exclusion(s, r, e) for s, r, e in entries))
    write_study(root, study)
    assert read_study(root) == study
