"""Writing a benchmark's generated report without losing the notes written by hand below it."""

from __future__ import annotations

from pathlib import Path

NOTES_MARK = "\n---\n\n## Notes"
"""Where a report's hand-written section starts: everything from it on is kept."""


def write_report(path: Path, text: str) -> None:
    """Write ``text`` to ``path``, keeping a hand-written notes section already at its end."""
    old = path.read_text() if path.is_file() else ""
    i = old.find(NOTES_MARK)
    path.write_text(text + (old[i:] if i >= 0 else ""))
