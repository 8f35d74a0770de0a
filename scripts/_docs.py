"""What every doc-writing script in scripts/ does last: print its Markdown, and with --write
put it into docs/ after the doc's hand-written introduction."""

from pathlib import Path

DOCS = Path(__file__).resolve().parent.parent / "docs"


def publish(markdown: str, doc: str, intro: str, write: bool, heading: str = "") -> None:
    """Print ``markdown``; if ``write``, docs/``doc`` = docs/``intro`` + ``heading`` + it."""
    print(markdown)
    if write:
        (DOCS / doc).write_text((DOCS / intro).read_text() + "\n" + heading + markdown + "\n")
