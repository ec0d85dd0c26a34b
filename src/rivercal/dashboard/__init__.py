"""The read-only web dashboard over a store (layer 7½)."""
