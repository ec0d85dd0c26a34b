"""``python -m rivercal.cli`` runs the command line."""

from rivercal.cli.main import main

main()
