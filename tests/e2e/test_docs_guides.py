"""Every command and code block of the guides runs as it is written.

Per page (the landing page, the how-to guides, the explanations), the fenced blocks are run in the order
of the page, as a reader would type them, in a fresh folder where ``docs`` is the repository's docs/
(the pages name their example folders as ``docs/howto/...``, relative to a clone): each ``$`` line of a
``console`` block through bash (continuation lines joined; a ``<<'TOML'`` here-document with its lines),
each ``python`` block as ``python block.py`` runs it, but in this process (as ``__main__``, its output
captured, warnings ignored as ``PYTHONWARNINGS=ignore`` would, its figures closed after it). A ``rivercal``
command with nothing for a shell to expand or redirect runs on the real app in this process
(:mod:`tests.cli`); its words are split as bash splits them. Both save each block or command the start of a
process with the numerical stack (about 1 s of processor time). A command or block that fails fails the test
with its output.

Two kinds of lines are not run as written: ``pip install`` (the ``dev`` extra that ``make test`` installs
already holds every extra), and ``rivercal dashboard``, a server that runs until stopped: it is started
on a free port, must answer its page, and is stopped.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import runpy
import shlex
import socket
import subprocess
import sys
import time
import traceback
import urllib.request
import warnings
from pathlib import Path

import pytest

from tests.cli import rivercal

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
FENCE = re.compile(r"^```(\w+)[^\n]*\n(.*?)^```", re.M | re.S)
#: What bash would expand, redirect or chain on a command line (a command with any of them goes to bash).
SHELL_SYNTAX = re.compile(r"[|&;<>()$`*?\[\]{}~\\\n]")

pytestmark = pytest.mark.slow


def blocks(page: Path) -> list[tuple[str, str]]:
    """(language, text) of every console and python block of a page, in order."""
    return [(lang, text) for lang, text in FENCE.findall(page.read_text(encoding="utf-8"))
            if lang in ("console", "python")]


PAGES = [page for page in (DOCS / "index.md", *sorted((DOCS / "howto").glob("*.md")),
                            *sorted((DOCS / "explanation").glob("*.md"))) if blocks(page)]


def commands(console: str) -> list[str]:
    """The commands of a console block: ``$`` lines, with continuation lines and here-documents."""
    out: list[str] = []
    lines = console.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        i += 1
        if not line.startswith("$ "):
            continue  # output shown in the block
        cmd = line[2:]
        while cmd.endswith("\\") and i < len(lines):
            cmd = cmd[:-1].rstrip() + " " + lines[i].strip()
            i += 1
        heredoc = re.search(r"<<'(\w+)'", cmd)
        if heredoc:
            body = []
            while i < len(lines) and lines[i] != heredoc.group(1):
                body.append(lines[i])
                i += 1
            i += 1
            cmd = "\n".join([cmd, *body, heredoc.group(1)])
        out.append(cmd)
    return out


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _serve_and_probe(cmd: str, cwd: Path, env: dict[str, str]) -> None:
    port = _free_port()
    argv = [*shlex.split(cmd), "--port", str(port)]
    server = subprocess.Popen(argv, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        deadline = time.monotonic() + 120
        while True:
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=5) as page:
                    assert page.status == 200 and b"rivercal" in page.read()
                    return
            except OSError:
                assert server.poll() is None, f"{cmd} ended: {server.communicate()[0][-3000:]}"
                assert time.monotonic() < deadline, f"{cmd}: no page on port {port} within 120 s"
                time.sleep(0.5)
    finally:
        server.terminate()
        server.wait(timeout=30)


def run_script(script: Path) -> str | None:
    """Run ``script`` in this process as ``python SCRIPT`` would (``__main__``, ``sys.argv``); None, or why it failed.

    Its standard output and error are captured (the error's text ends what is returned), warnings are ignored,
    and the figures it left open are closed.
    """
    out = io.StringIO()
    argv = sys.argv
    sys.argv = [str(script)]
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            runpy.run_path(str(script), run_name="__main__")
    except SystemExit as exc:
        if exc.code not in (None, 0):
            return f"{out.getvalue()}\nSystemExit({exc.code!r})"
    except Exception:
        return f"{out.getvalue()}\n{traceback.format_exc()}"
    finally:
        sys.argv = argv
        if "matplotlib.pyplot" in sys.modules:
            sys.modules["matplotlib.pyplot"].close("all")
    return None


@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(DOCS)) for p in PAGES])
def test_every_block_of_the_page_runs(page: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "docs").symlink_to(DOCS)
    monkeypatch.chdir(tmp_path)  # for the commands and blocks run in this process
    monkeypatch.setenv("MPLBACKEND", "Agg")
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}",
           "MPLBACKEND": "Agg", "PYTHONWARNINGS": "ignore"}
    ran = 0  # PAGES holds only pages with blocks; a page of pip lines alone would be a test that cannot fail
    for k, (lang, text) in enumerate(blocks(page)):
        if lang == "python":
            script = tmp_path / f"block{k}.py"
            script.write_text(text, encoding="utf-8")
            error = run_script(script)
            assert error is None, f"{page.name}, python block {k}:\n{text}\n{error[-4000:]}"
            ran += 1
            continue
        for cmd in commands(text):
            if cmd.startswith("pip install"):
                continue
            if cmd.startswith("rivercal dashboard"):
                _serve_and_probe(cmd, tmp_path, env)
                ran += 1
                continue
            if cmd.startswith("rivercal ") and not SHELL_SYNTAX.search(cmd.split("#")[0]):
                own = rivercal(*shlex.split(cmd, comments=True)[1:], env={"MPLBACKEND": "Agg"})
                assert own.returncode == 0, f"{page.name}: {cmd}\n{own.stdout[-2000:]}\n{own.stderr[-4000:]}"
                ran += 1
                continue
            run = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", cmd], cwd=tmp_path, env=env,
                                 capture_output=True, text=True, timeout=900)
            assert run.returncode == 0, f"{page.name}: {cmd}\n{run.stdout[-2000:]}\n{run.stderr[-4000:]}"
            ran += 1
    assert ran > 0, f"{page.name}: nothing ran"


def test_console_blocks_are_split_as_a_reader_types_them() -> None:
    text = "$ rivercal a \\\n    --b 1\noutput line\n$ cat >> f <<'TOML'\nx = 1\nTOML\n$ echo done\n"
    assert commands(text) == ["rivercal a --b 1", "cat >> f <<'TOML'\nx = 1\nTOML", "echo done"]
