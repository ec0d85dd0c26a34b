"""Command line (layer 8): parse, call the library, print."""
