"""Write the option table of ``run SCENE`` into docs/scenes.md, from the command line's registry.

``python tools/options_table.py`` replaces what stands between the markers
``<!-- options table: start -->`` and ``<!-- options table: end -->`` with
:func:`dolfinx_invertible.cli.option_table`; ``--check`` exits 1 if the file differs instead
(the tests run the same comparison).
"""

from __future__ import annotations

import sys
from pathlib import Path

from dolfinx_invertible.cli import option_table

DOCUMENT = Path(__file__).resolve().parent.parent / "docs" / "scenes.md"
START, END = "<!-- options table: start -->", "<!-- options table: end -->"


def rewritten(text: str) -> str:
    """Return ``text`` with the table between the markers generated afresh."""
    head, rest = text.split(START, 1)
    _, tail = rest.split(END, 1)
    return f"{head}{START}\n{option_table()}\n{END}{tail}"


if __name__ == "__main__":
    current = DOCUMENT.read_text(encoding="utf-8")
    wanted = rewritten(current)
    if "--check" in sys.argv[1:]:
        sys.exit(0 if wanted == current else 1)
    DOCUMENT.write_text(wanted, encoding="utf-8")
