"""What every doc-writing script in scripts/ does last: print its Markdown, and with --write
put it into docs/ after the doc's hand-written introduction, a template in scripts/templates/
(script inputs, not pages: docs/ holds only what users read)."""

from pathlib import Path

DOCS = Path(__file__).resolve().parent.parent / "docs"
TEMPLATES = Path(__file__).resolve().parent / "templates"


def publish(markdown: str, doc: str, intro: str, write: bool, heading: str = "") -> None:
    """Print ``markdown``; if ``write``, docs/``doc`` = scripts/templates/``intro`` + ``heading`` + it."""
    print(markdown)
    if write:
        (DOCS / doc).write_text((TEMPLATES / intro).read_text() + "\n" + heading + markdown + "\n")
