"""The account of an import: every object read, and whether it was converted exactly, approximated or refused.

One account for every importer (D-Flow FM, SOBEK 3, Mascaret): a subclass names the model's format in
``import.md``. It needs none of the importers' libraries.

``import.md`` in the case folder is written from it. A refusal that would change the hydraulics
(a structure, a boundary, a lateral, a branch) makes the import fail unless partial imports are
allowed; a refusal that does not (an observation point that lies nowhere, a display-only file) is
only listed.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar, Literal

from rivercal.errors import CaseError

if TYPE_CHECKING:
    from rivercal.case import Case

__all__ = ["Entry", "Ledger", "Status", "conclude", "remove_case"]

Status = Literal["exact", "approximated", "refused"]


@dataclass(frozen=True)
class Entry:
    """One object of the model and what became of it.

    Attributes
    ----------
    kind
        Kind of object (``branch``, ``profile``, ``weir``, ``lateral``, ``setting``, ...).
    id
        Its id (or name) in the model's files.
    status
        ``exact``, ``approximated`` or ``refused``.
    note
        How it was approximated and the expected effect, or why it was refused.
    hydraulic
        Whether a refusal changes the hydraulics (then the import fails unless partial imports are allowed).
    """

    kind: str
    id: str
    status: Status
    note: str = ""
    hydraulic: bool = True


_RANK = {"exact": 0, "approximated": 1, "refused": 2}


@dataclass
class Ledger:
    """The running account of an import (see the module docstring)."""

    #: The model's format, as ``import.md`` names it.
    MODEL: ClassVar[str] = "D-Flow FM"
    #: What the section of renamed ids says was wrong with them.
    RENAMED: ClassVar[str] = "Ids with characters a case does not allow ('#', spaces, ...) were renamed:"

    entries: list[Entry] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    renamed: dict[str, dict[str, str]] = field(default_factory=dict)
    errors: list[tuple[str, str]] = field(default_factory=list)
    parameters: list[str] = field(default_factory=list)

    def exact(self, kind: str, id_: str, note: str = "") -> None:
        """Record an object converted exactly."""
        self._add(Entry(kind, id_, "exact", note))

    def approximated(self, kind: str, id_: str, note: str) -> None:
        """Record an object converted with an approximation; ``note`` says how and the expected effect."""
        self._add(Entry(kind, id_, "approximated", note))

    def refused(self, kind: str, id_: str, note: str, *, hydraulic: bool = True) -> None:
        """Record an object that was not converted; ``note`` says why."""
        self._add(Entry(kind, id_, "refused", note, hydraulic))

    def _add(self, entry: Entry) -> None:
        """Record an entry; a second one for the same object keeps the worse status and both notes."""
        for k, e in enumerate(self.entries):
            if e.kind == entry.kind and e.id == entry.id:
                status = max(e.status, entry.status, key=_RANK.__getitem__)
                notes = [n for n, s in ((e.note, e.status), (entry.note, entry.status)) if n and s != "exact"]
                note = "; ".join(dict.fromkeys(notes)) or e.note or entry.note
                hydraulic = entry.hydraulic if entry.status == "refused" else e.hydraulic
                self.entries[k] = Entry(e.kind, e.id, status, note, hydraulic)
                return
        self.entries.append(entry)

    def error(self, where: str, text: str) -> None:
        """Record a value of the model files that cannot be used: ``where`` is ``file, line N``.

        Errors fail the import whatever the options: the file has to be corrected.
        """
        self.errors.append((where, text))

    def warn(self, text: str) -> None:
        """Record a warning about the files (an unknown keyword, a file read block by block), once."""
        if text not in self.warnings:
            self.warnings.append(text)

    def status_of(self, kind: str, id_: str) -> Status | None:
        """The status recorded last for an object, or None."""
        for e in reversed(self.entries):
            if e.kind == kind and e.id == id_:
                return e.status
        return None

    @property
    def blocking(self) -> list[Entry]:
        """Refusals that change the hydraulics."""
        return [e for e in self.entries if e.status == "refused" and e.hydraulic]

    def counts(self, status: Status) -> int:
        """Number of objects with a status."""
        return sum(1 for e in self.entries if e.status == status)

    def markdown(self, *, model: str, case_folder: str, partial: bool) -> str:
        """``import.md``: a summary table, the warnings, then every object by kind."""
        kinds = list(dict.fromkeys(e.kind for e in self.entries))
        per: dict[str, Counter] = {k: Counter() for k in kinds}
        for e in self.entries:
            per[e.kind][e.status] += 1
        lines = [
            f"# Import of a {self.MODEL} model",
            "",
            f"- model: `{model}`",
            f"- case: `{case_folder}`",
            f"- objects read: {len(self.entries)}; exact {self.counts('exact')}, approximated "
            f"{self.counts('approximated')}, refused {self.counts('refused')}",
        ]
        if partial and self.blocking:
            lines.append(f"- **partial import**: {len(self.blocking)} refused object(s) change the hydraulics; the "
                         "case leaves them out (allowed by --allow-partial)")
        lines += ["", "| kind | read | exact | approximated | refused |", "|---|---:|---:|---:|---:|"]
        for k in kinds:
            c = per[k]
            lines.append(f"| {k} | {sum(c.values())} | {c['exact']} | {c['approximated']} | {c['refused']} |")
        if self.errors:
            lines += ["", "## Errors", "", "Values of the model files that cannot be used; no case was written. "
                      "Correct them in the files named:", ""]
            lines += [f"- {where}: {text}" for where, text in self.errors]
        lines += ["", "## Warnings", ""]
        lines += [f"- {w}" for w in self.warnings] or ["None."]
        if self.renamed:
            lines += ["", "## Renamed ids", "", self.RENAMED, "", f"| kind | {self.MODEL} id | case id |",
                      "|---|---|---|"]
            for kind, names in self.renamed.items():
                lines += [f"| {kind} | `{old}` | `{new}` |" for old, new in names.items()]
        for status, title in (("refused", "Refused"), ("approximated", "Approximated")):
            chosen = [e for e in self.entries if e.status == status]
            lines += ["", f"## {title}", ""]
            if not chosen:
                lines.append("None.")
                continue
            lines += ["| kind | id | " + ("why" if status == "refused" else "how, and the expected effect") + " |",
                      "|---|---|---|"]
            groups: dict[tuple[str, str], list[str]] = {}
            for e in chosen:  # objects with the same note share a row
                groups.setdefault((e.kind, e.note), []).append(e.id)
            for (kind, note), ids in groups.items():
                lines.append(f"| {kind} | {', '.join(f'`{i}`' for i in ids)} | {_cell(note)} |")
        if self.parameters:
            lines += ["", "## Calibration parameters", "", "Written to case.toml so that the case can be calibrated "
                      "as imported (bounds from the model's own value; edit them to what you know):", ""]
            lines += [f"- {p}" for p in self.parameters]
        lines += ["", "## Converted exactly", ""]
        for k in kinds:
            ids = [e.id for e in self.entries if e.kind == k and e.status == "exact"]
            if ids:
                lines.append(f"- {k} ({len(ids)}): " + ", ".join(f"`{i}`" for i in ids))
        return "\n".join(lines) + "\n"


def conclude(ledger: Ledger, out: Path, source: Path, *, allow_partial: bool, write: Callable[[], None],
             locate: Callable[[str, str], str] | None = None, nothing_left: bool = False) -> Case:
    """The end of every import: ``import.md``, then the case, or the reasons there is none.

    Writes ``out/import.md`` from the ledger; then, when values of the model files cannot be used, or objects that
    change the hydraulics were refused (and partial imports are not allowed, or nothing would be left), removes
    an earlier import's case from ``out`` and raises a :class:`~rivercal.errors.CaseError` naming ``source``; else
    calls ``write`` (which writes ``case.toml`` and its series) and loads the case.

    Parameters
    ----------
    ledger
        The import's account.
    out
        The case folder.
    source
        The model's main file, named in the errors.
    allow_partial
        Whether refused objects that change the hydraulics may be left out.
    write
        Writes the case into ``out``.
    locate
        ``(kind, id) -> "file:line"`` of an object in the model's files, for the message (or none).
    nothing_left
        Whether leaving the refused objects out would leave nothing to run (then even a partial import fails).

    Raises
    ------
    CaseError
        For values that cannot be used or refusals that block (the message lists the first few).
    RuntimeError
        When the case written does not validate: every value read was checked, so that is a bug of the import.
    """
    from rivercal.case import load_case

    out.mkdir(parents=True, exist_ok=True)
    (out / "import.md").write_text(ledger.markdown(model=str(source), case_folder=str(out), partial=allow_partial),
                                   encoding="utf-8")
    if ledger.errors:
        remove_case(out)
        shown = "; ".join(f"{where}: {text}" for where, text in ledger.errors[:3])
        more = f" (and {len(ledger.errors) - 3} more)" if len(ledger.errors) > 3 else ""
        raise CaseError(f"{len(ledger.errors)} value(s) in the model files cannot be used: {shown}{more}; no case was "
                        f"written; see {out / 'import.md'}", file=str(source))
    if ledger.blocking and (not allow_partial or nothing_left):
        remove_case(out)
        groups: dict[tuple[str, str], list[str]] = {}
        for e in ledger.blocking:
            groups.setdefault((e.kind, e.note), []).append(e.id)

        def where(kind: str, ident: str) -> str:
            found = locate(kind, ident) if locate is not None else ""
            return f"{found}: " if found else ""

        shown = "; ".join(f"{where(kind, ids[0])}{kind} {ids[0]!r}" + (f" and {len(ids) - 1} more" if len(ids) > 1
                                                                        else "") + f": {note}"
                          for (kind, note), ids in list(groups.items())[:4])
        more = f" (and {len(groups) - 4} more reasons)" if len(groups) > 4 else ""
        raise CaseError(f"{len(ledger.blocking)} object(s) that change the hydraulics cannot be converted: "
                        f"{shown}{more}; no case was written; see {out / 'import.md'}"
                        + ("" if allow_partial else ", or import with --allow-partial to leave them out"),
                        file=str(source))
    write()
    try:
        return load_case(out)
    except CaseError as exc:
        remove_case(out)
        raise RuntimeError(f"the case made from {source.name} does not validate, which is a bug of the import (every "
                           f"value read was checked): {exc}") from None


def remove_case(out: Path) -> None:
    """An earlier import's case files, so that a failed import leaves no case that would run without what failed."""
    for old in [out / "case.toml", *out.glob("*.csv")]:
        if old.is_file():
            old.unlink()


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")
