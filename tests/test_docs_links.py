"""Every relative link in the repository's markdown resolves to a file in the repository.

Checked: README.md, CHANGELOG.md, docs/**/*.md and agents/*/README.md. A link is a markdown
link ``[text](target)`` (relative to the file it is in) or an inline-code span that is only a
repository path under ``docs/`` or ``agents/`` (relative to the repository root, the docs'
convention). Commands in code spans or fenced blocks name output folders, not files to
read, and are not checked. Run outputs leave git (CHANGELOG, "Repository"); this keeps the
prose that points at what stayed honest.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent

_FENCE = re.compile(r"^(```|~~~).*?^\1", re.M | re.S)
_LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
_CODE_PATH = re.compile(r"`((?:docs|agents)/[A-Za-z0-9_.\-/]*)`")
_EXTERNAL = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.\-]*:")  # http:, https:, mailto:, ...


def markdown_files(repo: Path) -> list[Path]:
    files = [repo / "README.md", repo / "CHANGELOG.md"]
    files += sorted((repo / "docs").rglob("*.md"))
    files += sorted((repo / "agents").glob("*/README.md"))
    return [f for f in files if f.is_file()]


def broken_links(md: Path, repo: Path) -> list[str]:
    """The relative targets in ``md`` that name no file or folder inside ``repo``."""
    text = _FENCE.sub("", md.read_text(encoding="utf-8"))
    root = repo.resolve()
    bad = []
    targets = [(t, md.parent) for t in _LINK.findall(text)]
    targets += [(t, repo) for t in _CODE_PATH.findall(text)]
    for target, base in targets:
        if _EXTERNAL.match(target) or target.startswith("#"):
            continue
        path = target.split("#", 1)[0]
        resolved = (base / path).resolve()
        if not resolved.is_relative_to(root) or not resolved.exists():
            bad.append(target)
    return bad


def test_the_checker_finds_a_broken_link_and_passes_a_good_one(tmp_path: Path) -> None:
    (tmp_path / "docs" / "a").mkdir(parents=True)
    (tmp_path / "docs" / "a" / "table.md").write_text("t")
    md = tmp_path / "docs" / "a" / "README.md"
    md.write_text(
        "[ok](table.md) [ok too](table.md#x) [web](https://example.org) [anchor](#top)\n"
        "[gone](old/run.csv) `docs/a/table.md` `docs/a/missing.png` [up](../../../outside.md)\n"
        "```bash\nrover-env benchmark --out docs/a/new-run [x](nowhere.md)\n```\n"
    )
    assert broken_links(md, tmp_path) == [
        "old/run.csv",
        "../../../outside.md",
        "docs/a/missing.png",
    ]


@pytest.mark.parametrize("md", markdown_files(REPO), ids=lambda p: str(p.relative_to(REPO)))
def test_every_relative_link_resolves(md: Path) -> None:
    assert broken_links(md, REPO) == []
