"""The README and the docs link only files that exist, name code paths that exist, and cite
publications instead of the internal specification numbers."""

import functools
import importlib.util
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
# Backticked repository paths: a top-level folder of the checkout, then a path.
CODE_PATH = re.compile(r"`((?:armgen|tests|benchmarks|examples|docs|generated|robots)/[A-Za-z0-9_./-]*)`")
MARKDOWN_LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")




@functools.cache
def _built_by_the_docs_hook() -> set[Path]:
    """The site files docs/hooks/armgen_docs.py generates during the build (CLI reference,
    figures): they exist in the site, not in the checkout."""
    spec = importlib.util.spec_from_file_location("armgen_docs_hook", REPO / "docs" / "hooks" / "armgen_docs.py")
    hook = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hook)
    return {(REPO / "docs" / uri).resolve() for uri in hook.generated_files()}


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_links_and_code_paths_exist(page):
    text = page.read_text(encoding="utf-8")
    missing = []
    for target in MARKDOWN_LINK.findall(text):
        if re.match(r"[a-z]+://", target):
            continue
        built = page.parent.resolve() == (REPO / "docs").resolve() and \
            (page.parent / target).resolve() in _built_by_the_docs_hook()
        if not (page.parent / target).exists() and not built:
            missing.append(target)
    for path in CODE_PATH.findall(text):
        if "*" not in path and "<" not in path and not (REPO / path).exists():
            missing.append(path)
    assert not missing, f"{page.name} names files that do not exist: {missing}"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_no_internal_spec_references(page):
    text = page.read_text(encoding="utf-8")
    assert not re.search(r"\bspec[ -]\d\d\b|shared/spec", text, re.IGNORECASE), \
        f"{page.name} points at the internal specs; cite the publication or link the docs page"
