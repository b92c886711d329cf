"""The study's HTML report: rendered from a synthetic study and opened in headless chromium
(once for the module) - it shows every section and figure, fetches nothing, logs no error -
plus escaping, refusal to overwrite and number formatting without a browser."""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Iterator
from pathlib import Path

import pytest
from browser import LoadedPage, open_page
from report_data import EXCLUDED_REASON, EXCLUDED_SESSION, expected_figures, study_report

from hilrig.analysis.report import shown_unit
from hilrig.errors import OutputError
from hilrig.study import report_html
from hilrig.study.records import StudyReport, metric_unit
from hilrig.study.report_html import MINUS, MISSING, TIMES, number, p_text

SECTIONS = (
    "Design",
    "Sessions",
    "Exclusions",
    "Cartesian axes (x, y, z)",
    "Joints",
    "Notes",
    "How to reproduce",
)


@pytest.fixture(scope="module")
def report() -> StudyReport:
    return study_report()


@pytest.fixture(scope="module")
def rendered(report: StudyReport) -> tuple[str, list[str]]:
    """The document and the titles the progress hook was called with."""
    drawn: list[str] = []
    return report_html.render(report, progress=drawn.append), drawn


@pytest.fixture(scope="module")
def loaded(
    rendered: tuple[str, list[str]], tmp_path_factory: pytest.TempPathFactory
) -> Iterator[LoadedPage]:
    path = tmp_path_factory.mktemp("report") / "report.html"
    path.write_text(rendered[0], encoding="utf-8")
    with open_page(path) as page:
        yield page


# --- in the browser ---------------------------------------------------------------------------


def test_the_page_renders_with_its_title_and_sections(
    loaded: LoadedPage, report: StudyReport
) -> None:
    page = loaded.page
    assert page.title() == f"Study report: {report.name}"
    assert page.locator("h1").inner_text() == f"Study report: {report.name}"
    headings = [h.strip() for h in page.locator("h2").all_inner_texts()]
    assert headings == list(SECTIONS)
    for group in ("cartesian", "joint"):
        subheadings = page.locator(f"#group-{group} h3").all_inner_texts()
        assert subheadings == [
            "Comparison with the baseline",
            "Distribution of subject values",
            "Representative events",
        ]
    assert report.command in page.locator("#reproduce pre").inner_text()


def test_every_figure_is_an_inline_svg_with_a_box(loaded: LoadedPage, report: StudyReport) -> None:
    figures = loaded.page.locator("figure svg.figure")
    assert figures.count() == expected_figures(report) == 18
    for index in range(figures.count()):
        svg = figures.nth(index)
        box = svg.bounding_box()
        assert box is not None and box["width"] > 100 and box["height"] > 100
        assert svg.get_attribute("role") == "img"
        assert (svg.get_attribute("aria-label") or "").strip()
        assert svg.locator("title").count() == 1
    assert loaded.page.locator("img, link, script, iframe, object, embed").count() == 0


def test_the_only_request_is_the_file_itself(loaded: LoadedPage) -> None:
    assert loaded.requests == [loaded.url]


def test_no_console_error_and_no_page_error(loaded: LoadedPage) -> None:
    assert loaded.errors == []
    assert [text for kind, text in loaded.console if kind in ("error", "warning")] == []


def test_the_excluded_session_is_marked_with_its_reason(loaded: LoadedPage) -> None:
    page = loaded.page
    excluded = page.locator("table.catalogue tr.excluded")
    assert EXCLUDED_SESSION in excluded.first.inner_text()
    assert EXCLUDED_REASON in page.locator("table.catalogue tr.reason").inner_text()
    row = page.locator("#exclusions tbody tr")
    assert row.count() == 1
    assert EXCLUDED_SESSION in row.inner_text() and EXCLUDED_REASON in row.inner_text()
    assert "1 session, 3 events" in row.inner_text()
    flagged = page.locator("table.catalogue .badge.flag").all_inner_texts()
    assert {"dropped_ticks", "force_saturated", "late_start"} <= set(flagged)


def test_a_comparison_is_shown_formatted(loaded: LoadedPage, report: StudyReport) -> None:
    frame = report.comparisons
    r = frame[(frame["group"] == "cartesian") & (frame["metric"] == "max_abs_offset")].iloc[0]
    _, factor = shown_unit(metric_unit("max_abs_offset", "cartesian"))
    assert factor == 1000.0  # metres shown in mm
    row = loaded.page.locator(
        "#group-cartesian table.comparisons tbody tr", has_text="maximum offset (mm)"
    )
    cells = [c.strip() for c in row.locator("td").all_inner_texts()]
    difference = number(float(r["median_difference"]) * factor, signed=True)
    assert re.fullmatch(rf"[+{MINUS}]\d+\.\d", difference)  # e.g. +26.1 (three significant digits)
    assert difference in cells
    assert number(float(r["median_baseline"]) * factor) in cells
    assert p_text(float(r["p_adjusted"])) in cells


# --- without a browser -------------------------------------------------------------------------


def test_the_progress_hook_is_called_once_per_figure(
    rendered: tuple[str, list[str]], report: StudyReport
) -> None:
    assert len(rendered[1]) == expected_figures(report)
    assert rendered[0].count("<svg ") == expected_figures(report)


def test_hostile_text_is_escaped() -> None:
    hostile = '<script>alert("x")</script>'
    report = study_report(exclusion_reason=hostile)
    report = dataclasses.replace(
        report,
        name=f"study {hostile}",
        notes=(hostile,),
        curves=tuple(
            dataclasses.replace(c, condition=f"{c.condition} -->{hostile}") for c in report.curves
        ),
    )
    document = report_html.render(report)
    assert "<script" not in document
    assert document.count("&lt;script&gt;alert(&#34;x&#34;)&lt;/script&gt;") >= 4


def test_a_study_with_nothing_to_compare_renders_its_sessions(report: StudyReport) -> None:
    empty = dataclasses.replace(
        report,
        exclusions=report.exclusions.iloc[:0],
        observations=report.observations.iloc[:0],
        subject_values=report.subject_values.iloc[:0],
        distributions=report.distributions.iloc[:0],
        comparisons=report.comparisons.iloc[:0],
        curves=(),
        notes=(),
    )
    drawn: list[str] = []
    document = report_html.render(empty, progress=drawn.append)
    assert drawn == [] and "<svg" not in document
    assert "Nothing was excluded." in document and "No quality warnings." in document
    assert EXCLUDED_SESSION in document  # the catalogue still lists every session


def test_the_document_references_nothing_outside_itself(rendered: tuple[str, list[str]]) -> None:
    document = rendered[0]
    assert not re.search(r"""(src|href)\s*=\s*["']?\s*(https?:|//)""", document, re.IGNORECASE)
    assert not re.search(r"url\(\s*['\"]?\s*(https?:|//)", document, re.IGNORECASE)
    assert "@import" not in document and "<link" not in document
    assert "http://" not in document and "https://" not in document
    assert " src=" not in document
    hrefs = re.findall(r"""\shref=["']([^"']*)""", document)
    assert hrefs and all(h.startswith("#") for h in hrefs)  # in-page links and svg uses only


def test_an_existing_file_is_refused_unless_overwrite(tmp_path: Path) -> None:
    path = tmp_path / "report.html"
    path.write_text("earlier report", encoding="utf-8")
    report = study_report()
    with pytest.raises(OutputError) as caught:
        report_html.write_report(report, path)
    assert str(caught.value) == f"{path}: already exists; pass --overwrite to replace it"
    assert path.read_text(encoding="utf-8") == "earlier report"
    assert report_html.write_report(report, path, overwrite=True) == path
    assert path.read_text(encoding="utf-8").startswith("<!DOCTYPE html>")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.html"]


def test_a_missing_folder_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "absent" / "report.html"
    with pytest.raises(OutputError, match="does not exist"):
        report_html.write_report(study_report(), path)


@pytest.mark.parametrize(
    ("value", "shown"),
    [
        (6, "6"),
        (47500, "47,500"),
        (3.0, "3.00"),
        (176.3, "176"),
        (-20.089, f"{MINUS}20.1"),
        (0.0216, "0.0216"),
        (0.000855, "0.000855"),
        (4.2e-5, f"4.20{TIMES}10⁻⁵"),
        (1234.5, "1,234"),
        (float("nan"), MISSING),
        (True, "yes"),
    ],
)
def test_numbers_have_three_significant_digits(value: object, shown: str) -> None:
    assert number(value) == shown


def test_signed_numbers_and_p_values() -> None:
    assert number(26.09, signed=True) == "+26.1"
    assert number(-0.699, signed=True) == f"{MINUS}0.699"
    assert p_text(0.0004) == "<0.001"
    assert p_text(0.0625) == "0.062"
    assert p_text(float("nan")) == MISSING
