"""The FEWS how-to writes only below ``out/`` of the clone (which git ignores), never into its root.

``tests/e2e/test_docs_guides.py`` runs the page's commands; this test reads them and checks where each one
writes: the target of ``cp`` and ``mkdir``, ``--out`` of ``rivercal simulate``, the files a Python block
writes, and the run file ``rivercal fews`` is given (the module writes into that file's folder).
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "howto" / "fews.md"
FENCE = re.compile(r"^```(console|python)[^\n]*\n(.*?)^```", re.M | re.S)


def _written(page: Path) -> list[str]:
    """Every path the page's commands write to, as written on the page."""
    out: list[str] = []
    for lang, text in FENCE.findall(page.read_text(encoding="utf-8")):
        if lang == "python":
            out += re.findall(r"write_\w+\(\s*\"([^\"]+)\"", text)
            continue
        for line in (ln[2:] for ln in text.splitlines() if ln.startswith("$ ")):
            for command in re.split(r"&&|;", line):
                words = shlex.split(command)
                if not words:
                    continue
                if words[0] == "cp":
                    out.append(words[-1])
                elif words[0] == "mkdir":
                    out += [w for w in words[1:] if not w.startswith("-")]
                elif words[:2] == ["rivercal", "fews"]:
                    out.append(str(Path(words[-1]).parent))
                elif "--out" in words:
                    out.append(words[words.index("--out") + 1])
    return out


def test_the_fews_how_to_writes_below_out_only() -> None:
    written = _written(PAGE)
    assert any(w.startswith("out/fews/module") for w in written)  # the commands were found
    assert len(written) >= 5, written
    stray = [w for w in written if not w.startswith("out/")]
    assert not stray, f"the how-to writes outside out/: {stray}"
    assert "out/" in (ROOT / ".gitignore").read_text(encoding="utf-8").split()
