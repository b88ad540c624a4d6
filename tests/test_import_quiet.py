"""Importing mechsweep changes nothing outside it: no environment variable, no numba function or
option, no numba module imported early, no source file read and no folder made; what a kernel needs
is done when mechsweep first compiles or loads one (tests/engine/test_jit.py)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import mechsweep

PACKAGE = str(Path(mechsweep.__file__).resolve().parent)

CODE = """
import collections, json, os, sys
import numba, numba.np.linalg
from numba.core import config

env = dict(os.environ)
ensure_blas, cache_dir = numba.np.linalg.ensure_blas, config.CACHE_DIR
numba_modules = {k: v for k, v in sys.modules.items() if k == "numba" or k.startswith("numba.")}
opened = collections.Counter()


def audit(event, args):  # every file opened from here on (import's reads included)
    if event == "open" and isinstance(args[0], str) and args[0].endswith(".py"):
        opened[os.path.realpath(args[0])] += 1


sys.addaudithook(audit)
import mechsweep, mechsweep.model, mechsweep.figures
from mechsweep import _jit

with mechsweep.open_dataset(sys.argv[2]) as ds:
    ds.load()
imported = {os.path.realpath(m.__file__) for m in list(sys.modules.values()) if getattr(m, "__file__", None)}
mine = {path: n for path, n in opened.items() if path.startswith(sys.argv[1] + os.sep)}
print(json.dumps({
    "environ": sorted(set(os.environ.items()) ^ set(env.items())),
    "ensure_blas": numba.np.linalg.ensure_blas is ensure_blas,
    "numba_cache_dir": config.CACHE_DIR == cache_dir,
    "numba_modules": sorted(k for k, v in numba_modules.items() if sys.modules.get(k) is not v),
    "arraymath": "numba.np.arraymath" in sys.modules,
    "hash_computed": bool(_jit._PACKAGE_HASH),
    "read_not_imported": sorted(p for p in mine if p not in imported),  # a hash of the tree reads them all
    "read_twice": sorted(p for p, n in mine.items() if n > 1),  # numba's cache stamps the file of a function
}))
"""


def test_importing_mechsweep_and_reading_a_dataset_leave_the_process_as_it_was(in_tmp, small_duffing, tmp_path):
    mechsweep.run(small_duffing, output="data/runs/s.h5")
    cache = tmp_path / "cache"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path), "MECHSWEEP_CACHE_DIR": str(cache)}
    env.pop("OMP_WAIT_POLICY", None)
    out = subprocess.run([sys.executable, "-c", CODE, PACKAGE, "data/runs/s.h5"], capture_output=True, text=True,
                         cwd=in_tmp, env=env)
    assert out.returncode == 0, out.stderr
    seen = json.loads(out.stdout.strip().splitlines()[-1])
    assert seen == {"environ": [], "ensure_blas": True, "numba_cache_dir": True, "numba_modules": [],
                    "arraymath": False, "hash_computed": False,
                    "read_not_imported": [], "read_twice": []}
    assert not cache.exists()  # no cache folder made
