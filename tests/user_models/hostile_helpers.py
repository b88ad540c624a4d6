"""Helpers of tests/user_models/hostile_writes.py in a module of their own (imported by name: its
folder must be on sys.path). ``negate`` writes its argument where the source shows it; ``hidden``
does too, but is made from a string, so no source of it can be read: only the load-time call at
the probe point sees its write."""
import numba


@numba.njit
def negate(v, k):
    v[k] = -v[k]


_NS: dict = {}
exec("def hidden(v):\n    v[1] = 0.5 * v[1] + 1.0\n", _NS)
hidden = _NS["hidden"]
