"""The account of a Mascaret import: every object read, converted exactly, approximated (how) or refused (why).

``import.md`` in the case folder is written from it. A refusal that changes the hydraulics (a reach, a
boundary, a lateral, a weir, a friction zone) makes the import fail unless partial imports are allowed;
one that does not (a tracer, an output setting) is only listed. The same discipline as the D-HYDRO
import, kept separate so that reading a Mascaret model needs neither hydrolib-core nor the D-HYDRO code.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Literal

__all__ = ["Entry", "Ledger", "Status"]

Status = Literal["exact", "approximated", "refused"]
_RANK = {"exact": 0, "approximated": 1, "refused": 2}


@dataclass(frozen=True)
class Entry:
    """One object of the Mascaret model and what became of it.

    Attributes
    ----------
    kind
        Kind of object (``reach``, ``profile``, ``boundary``, ``lateral``, ``friction zone``, ``setting``, ...).
    id
        Its name or number in the Mascaret files.
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


@dataclass
class Ledger:
    """The running account of an import (see the module docstring)."""

    entries: list[Entry] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    renamed: dict[str, dict[str, str]] = field(default_factory=dict)

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

    def warn(self, text: str) -> None:
        """Record a warning about the files (an element that was not read, a value out of the usual)."""
        if text not in self.warnings:
            self.warnings.append(text)

    def status_of(self, kind: str, id_: str) -> Status | None:
        """The status recorded for an object, or None."""
        for e in self.entries:
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
            "# Import of a Mascaret model",
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
        lines += ["", "## Warnings", ""]
        lines += [f"- {w}" for w in self.warnings] or ["None."]
        if self.renamed:
            lines += ["", "## Renamed ids", "", "Names with characters a case does not allow (spaces, accents, ...) "
                      "or used twice were renamed:", "", "| kind | Mascaret name | case id |", "|---|---|---|"]
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
        lines += ["", "## Converted exactly", ""]
        for k in kinds:
            done = [e for e in self.entries if e.kind == k and e.status == "exact"]
            if done:
                lines.append(f"- {k} ({len(done)}): " + ", ".join(f"`{e.id}`" for e in done))
        return "\n".join(lines) + "\n"


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")
