"""The tests' way of evaluating points (tests/evaluating.py), for the measurement scripts here,
which import it as ``points`` with tests/data on sys.path."""
import sys
from pathlib import Path

_REPO = str(Path(__file__).resolve().parents[2])
if _REPO not in sys.path:  # tests.evaluating, whatever folder a script runs from
    sys.path.insert(0, _REPO)

from tests.evaluating import blank_outputs, evaluate  # noqa: E402

__all__ = ["blank_outputs", "evaluate"]
