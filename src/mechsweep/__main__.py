"""`python -m mechsweep ...`: the same as the `mechsweep` command."""
import sys

from .cli import main

sys.exit(main())
