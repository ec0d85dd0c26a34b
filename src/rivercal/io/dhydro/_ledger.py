"""The account of a D-Flow FM import (:mod:`rivercal.io.ledger`, shared by every importer)."""

from rivercal.io.ledger import Entry, Ledger, Status

__all__ = ["Entry", "Ledger", "Status"]
