"""`python -m mechsweep ...`: the same as the `mechsweep` command."""
from .cli import script

script()
