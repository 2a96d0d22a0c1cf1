"""CITATION.cff is valid Citation File Format 1.2, and each method page and the results page
cite the publication the method was reconstructed from as CITATION.cff records it."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from cffconvert.cli.create_citation import create_citation

REPO = Path(__file__).resolve().parent.parent
METHOD_PAGES = ("cartesian.md", "fault_tolerance.md", "wgpm.md", "ptp.md", "snake.md")
PAPER_BULLET = re.compile(r"^“The paper” on this page is.*?\n\n- (.*)$", re.M)


@pytest.fixture(scope="module")
def citation():
    return create_citation(str(REPO / "CITATION.cff"), None)


def _sources(citation) -> dict[str, dict]:
    """The references that name the docs page of their method, by page."""
    found = {}
    for ref in citation.cffobj["references"]:
        page = re.search(r"\(docs/(\w+\.md)\)", ref.get("notes", ""))
        if page:
            found[page.group(1)] = ref
    return found


def _paper_bullet(page: str) -> str:
    match = PAPER_BULLET.search((REPO / "docs" / page).read_text(encoding="utf-8"))
    assert match, f"docs/{page}: no “The paper” citation under References"
    return match.group(1)


def test_citation_file_is_valid_cff_1_2(citation):
    citation.validate()  # raises on a schema violation
    assert citation.cffobj["cff-version"] == "1.2.0"


def test_every_method_has_its_source_publication(citation):
    assert sorted(_sources(citation)) == sorted(METHOD_PAGES)


@pytest.mark.parametrize("page", METHOD_PAGES)
def test_method_page_cites_its_paper_as_the_citation_file_does(citation, page):
    ref = _sources(citation)[page]
    bullet = _paper_bullet(page)
    assert ref["title"] in bullet
    for author in ref["authors"]:
        name = author.get("name") or f"{author['family-names']} {author['given-names']}"
        assert name in bullet, name
        if "alias" in author:
            assert author["alias"] in bullet
    for key in ("journal", "year", "volume", "issue", "start", "end", "issn"):
        if key in ref:
            value = str(ref[key]).split(" (")[0]  # the journal's name before its Chinese name
            assert value in bullet, (key, value)


@pytest.mark.parametrize("page", METHOD_PAGES)
def test_results_page_lists_each_paper_as_its_method_page(page):
    results = (REPO / "docs" / "results.md").read_text(encoding="utf-8")
    assert f"]({page}): {_paper_bullet(page)[0].upper()}{_paper_bullet(page)[1:]}" in results


def test_what_a_source_leaves_unstated_is_marked(citation):
    sources = _sources(citation)
    ptp = sources["ptp.md"]
    assert ptp["title"] == "not stated in the copy" and ptp["authors"] == [{"name": "not stated in the copy"}]
    assert "year" not in ptp and "journal" not in ptp
    assert "Patent number: not stated" in sources["wgpm.md"]["notes"] and "number" not in sources["wgpm.md"]
    assert "year of publication and pages: not stated" in sources["cartesian.md"]["notes"]
    assert "volume: not stated" in sources["fault_tolerance.md"]["notes"] and "volume" not in sources["fault_tolerance.md"]
