"""The account of a Mascaret import (:mod:`rivercal.io.ledger`, shared by every importer).

A refusal that changes the hydraulics (a reach, a boundary, a lateral, a weir, a friction zone) makes the
import fail unless partial imports are allowed; one that does not (a tracer, an output setting) is only listed.
"""

from __future__ import annotations

from typing import ClassVar

from rivercal.io.ledger import Entry, Status
from rivercal.io.ledger import Ledger as _Ledger

__all__ = ["Entry", "Ledger", "Status"]


class Ledger(_Ledger):
    """The import's account, titled for a Mascaret model in ``import.md``."""

    MODEL: ClassVar[str] = "Mascaret"
    RENAMED: ClassVar[str] = ("Names with characters a case does not allow (spaces, accents, ...) or used twice were "
                              "renamed:")
