"""A run stopped by Ctrl-C after a given number of chunks, for the tests of interrupted runs (their
resume, their journal, their damaged chunk files): one helper instead of a copy per test file."""
import contextlib

import pytest

from mechsweep.execution import execute, runner


@contextlib.contextmanager
def interrupted_after(after: int):
    """Within it, a run is stopped (KeyboardInterrupt, as Ctrl-C) when chunk ``after`` + 1 is about
    to be computed: the first ``after`` chunks are computed (and saved) by the real
    ``execute.evaluate_chunk``."""
    real, calls = execute.evaluate_chunk, [0]

    def interrupted(*args):
        calls[0] += 1
        if calls[0] > after:
            raise KeyboardInterrupt
        return real(*args)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(execute, "evaluate_chunk", interrupted)
        yield
