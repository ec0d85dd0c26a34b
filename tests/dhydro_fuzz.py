"""Mutations of a D-Flow FM model folder, for the fuzz test of the D-HYDRO import (tests/unit/test_dhydro_fuzz.py).

Each mutation damages one file of a copy of a real model the way files get damaged in practice: a value
replaced by nonsense (``nan``, ``-5``, ``1e30``, text, a path out of the folder), a key renamed, removed
or given twice, a section header lost or repeated, a file truncated, deleted or overwritten with bytes.
:func:`run_case` imports the damaged model and says what happened.

``python -m tests.dhydro_fuzz N SEED`` runs N mutations from SEED and prints every case that ends in
anything but a case or a clean error (for a longer search than the test's).
"""

from __future__ import annotations

import random
import re
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

#: Values a mutation puts in place of a value.
NONSENSE = ("nan", "NaN", "inf", "-inf", "-1e30", "1e30", "0", "-5", "-0.001", "abc", "", "1 2 3", "#", "x" * 300,
            "realtime", "../../outside.ini", "/etc/passwd", "2e308", "1,5", "true", "-999", "99999999999999999999")
_KEY_VALUE = re.compile(r"^(\s*)([^=#\[\]\s][^=]*?)(\s*=\s*)(.*?)(\s*(#.*)?)$")


@dataclass(frozen=True)
class Outcome:
    """What an import of a damaged model did: ``case``, ``error`` (a clean CaseError) or ``crash``."""

    kind: str
    message: str


def snapshot(root: Path, skip: Path) -> dict[str, tuple[int, int]]:
    """Size and modification time of every file under ``root`` except under ``skip``."""
    out = {}
    for p in root.rglob("*"):
        if p.is_file() and skip not in p.parents:
            st = p.stat()
            out[str(p)] = (st.st_size, st.st_mtime_ns)
    return out


def mutate(model: Path, rng: random.Random) -> str:
    """Damage one file of the model folder ``model``; returns what was done."""
    files = sorted(p for p in model.iterdir() if p.is_file() and p.suffix != ".md")
    text_files = [p for p in files if p.suffix in (".mdu", ".ini", ".ext", ".bc")]
    kind = rng.choice(["value", "value", "value", "value", "key", "section", "truncate", "delete", "bytes", "row"])
    if kind in ("truncate", "delete", "bytes"):
        target = rng.choice(files)
    elif kind == "row":
        target = next((p for p in text_files if p.suffix == ".bc"), rng.choice(text_files))
    else:
        target = rng.choice(text_files)
    name = target.name
    if kind == "delete":
        target.unlink()
        return f"deleted {name}"
    data = target.read_bytes()
    if kind == "truncate":
        cut = rng.randrange(0, max(len(data), 1))
        target.write_bytes(data[:cut])
        return f"truncated {name} at byte {cut}"
    if kind == "bytes":
        buf = bytearray(data)
        for _ in range(rng.randint(1, 8)):
            if buf:
                buf[rng.randrange(len(buf))] = rng.randrange(256)
        target.write_bytes(bytes(buf))
        return f"flipped bytes in {name}"
    lines = data.decode("utf-8", errors="replace").splitlines()
    if kind == "row":
        rows = [k for k, line in enumerate(lines) if line.strip() and line.strip()[0] in "-0123456789."
                and "=" not in line]
        if rows:
            k = rng.choice(rows)
            parts = lines[k].split()
            j = rng.randrange(len(parts))
            parts[j] = rng.choice(["nan", "abc", "1e400", "-inf", ""])
            lines[k] = "    ".join(parts)
            target.write_text("\n".join(lines) + "\n", encoding="utf-8")
            return f"{name} line {k + 1}: data row -> {lines[k]!r}"
        kind = "value"
    keyed = [k for k, line in enumerate(lines) if _KEY_VALUE.match(line)]
    headers = [k for k, line in enumerate(lines) if line.strip().startswith("[")]
    if kind == "section" and headers:
        k = rng.choice(headers)
        how = rng.choice(["drop", "repeat", "rename"])
        if how == "drop":
            del lines[k]
        elif how == "repeat":
            lines.insert(k, lines[k])
        else:
            lines[k] = "[" + rng.choice(["Foo", "structure", "Weir", "General", ""]) + "]"
        target.write_text("\n".join(lines) + "\n", encoding="utf-8")
        return f"{name} line {k + 1}: section header {how}"
    if not keyed:
        target.write_text("garbage\n", encoding="utf-8")
        return f"{name}: replaced by garbage"
    k = rng.choice(keyed)
    m = _KEY_VALUE.match(lines[k])
    indent, key, eq, value, comment = m.group(1), m.group(2), m.group(3), m.group(4), m.group(5) or ""
    if kind == "key":
        how = rng.choice(["rename", "drop", "twice", "twice-other"])
        if how == "rename":
            lines[k] = f"{indent}{key}X{eq}{value}{comment}"
        elif how == "drop":
            del lines[k]
        elif how == "twice":
            lines.insert(k + 1, lines[k])
        else:
            lines.insert(k + 1, f"{indent}{key}{eq}{rng.choice(NONSENSE)}")
        target.write_text("\n".join(lines) + "\n", encoding="utf-8")
        return f"{name} line {k + 1}: key {key!r} {how}"
    new = rng.choice(NONSENSE)
    if rng.random() < 0.3 and value.split():  # one number of a list
        parts = value.split()
        parts[rng.randrange(len(parts))] = new or "nan"
        new = " ".join(parts)
    lines[k] = f"{indent}{key}{eq}{new}{comment}"
    target.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return f"{name} line {k + 1}: {key} = {new!r} (was {value!r})"


def run_case(mdu: Path, out: Path, **options) -> Outcome:
    """Import a model; ``case`` when a case was written and loads, ``error`` for a CaseError, ``crash`` otherwise."""
    from rivercal.case import load_case
    from rivercal.errors import CaseError
    from rivercal.io.dhydro import ImportOptions, import_dhydro

    try:
        import_dhydro(mdu, out, ImportOptions(**options))
    except CaseError as exc:
        return Outcome("error", str(exc))
    except Exception as exc:
        import traceback

        return Outcome("crash", f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}")
    load_case(out)
    return Outcome("case", "")


def names_a_file(message: str, names: set[str], mdu: Path) -> bool:
    """Whether an error message says where the problem is.

    ``names`` are the file names of the model before it was damaged. The message must name one of them (or an
    option) after the leading ``<model file>:`` that every import error carries, or be about the model file
    itself and name the line or section.
    """
    body = message.split(f"{mdu}: ", 1)[1] if message.startswith(f"{mdu}: ") else message
    if any(n and n in body for n in names | {"--out", "--dt", "--realtime-lateral"}):
        return True
    return message.startswith(str(mdu)) and ("line " in body or "model file" in body or "[" in body)


def main(count: int, seed: int, bases: list[Path], verbose: bool = False) -> int:  # pragma: no cover - a tool

    """Run ``count`` mutations; print the ones that crash or give an error naming no file."""
    import tempfile

    rng = random.Random(seed)
    bad = 0
    for k in range(count):
        base = bases[k % len(bases)]
        with tempfile.TemporaryDirectory() as tmp:
            model = Path(tmp) / "model"
            shutil.copytree(base.parent, model)
            names = {p.name for p in model.rglob("*")}
            what = mutate(model, rng)
            if verbose:
                print(f"... {k}: {what}", flush=True)
            before = snapshot(Path(tmp), Path(tmp) / "case")
            result = run_case(model / base.name, Path(tmp) / "case", allow_partial=rng.random() < 0.5,
                              realtime_lateral=0.01)
            after = snapshot(Path(tmp), Path(tmp) / "case")
            if result.kind == "crash" or before != after or (
                    result.kind == "error" and not names_a_file(result.message, names, model / base.name)):
                bad += 1
                print(f"--- {k}: {base.parent.name}: {what}\n{result.kind}: {result.message[:3000]}")
    print(f"{bad} of {count} bad")
    return bad


if __name__ == "__main__":  # pragma: no cover
    sys.exit(min(main(int(sys.argv[1]), int(sys.argv[2]), [Path(p) for p in sys.argv[3:] if p != "-v"],
                      verbose="-v" in sys.argv), 1))
