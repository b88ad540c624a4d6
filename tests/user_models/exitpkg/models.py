"""Ends the process while it is imported."""
raise SystemExit("bye")
