"""Imported by tests/user_models/exit_via_helper.py: ends the process at import (its folder must be
on sys.path)."""
import sys

sys.exit(3)
