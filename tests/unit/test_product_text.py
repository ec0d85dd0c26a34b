"""Product text speaks to users: no reference to this project's issue tracker in code, docs or README.

Citations of another project's tracker (a line that names OpenDA, e.g. ``OpenDA issue 449``) are
references to their discussion, not ours, and stay.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
OURS = re.compile(r"\b(issue|ticket)s?\s+#?\d+", re.IGNORECASE)


def test_no_issue_numbers_in_product_text() -> None:
    files = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md")),
             *sorted((ROOT / "src" / "rivercal").rglob("*"))]
    found = []
    for path in files:
        if path.suffix not in (".py", ".md", ".toml", ".html", ".txt") or not path.is_file():
            continue
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if OURS.search(line) and "OpenDA" not in line:
                found.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert not found, "\n".join(found)
