"""The docs hold true: every file README.md and docs/*.md link to or cite exists (a test
moved to a folder is cited by its new path), and a cited test function exists in its file."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
_LINK = re.compile(r"\]\(([^)\s]+)\)")
_CITED = re.compile(
    r"(?<![\w/.-])((?:tests|bench|scripts|src|docs|plugins|examples|so101sim)/[\w/.-]+"
    r"\.(?:py|md|toml|txt|json|ya?ml|sh|png))(?:::(\w+))?"
)


def _exists(doc: Path, cited: str) -> bool:
    """A path as the docs write it: from the repository's root, from ``src/`` (module paths
    written ``so101sim/...``) or from the document's folder."""
    return any(p.exists() for p in (ROOT / cited, ROOT / "src" / cited, doc.parent / cited))


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_every_linked_file_exists(doc):
    missing = []
    for link in _LINK.findall(doc.read_text(encoding="utf-8")):
        target = link.split("#", 1)[0]
        url = re.match(r"[a-z][a-z0-9+.-]*:", target)
        if target and not url and not (doc.parent / target).exists():  # not a URL or anchor
            missing.append(target)
    assert not missing, f"{doc.name} links to files that do not exist: {missing}"


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_every_cited_path_and_test_exists(doc):
    missing = []
    for path, function in _CITED.findall(doc.read_text(encoding="utf-8")):
        if not _exists(doc, path):
            missing.append(path)
        elif function:
            source = next(
                p for p in (ROOT / path, ROOT / "src" / path, doc.parent / path) if p.exists()
            )
            if not re.search(rf"^\s*(?:async\s+)?def {function}\b", source.read_text(), re.M):
                missing.append(f"{path}::{function}")
    assert not missing, (
        f"{doc.name} cites paths or tests that do not exist: {missing}; expected their "
        "current paths (tests live in folders: tests/<package>/...)"
    )
