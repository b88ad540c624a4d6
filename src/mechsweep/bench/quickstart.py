"""`mechsweep bench quickstart`: the README's main job timed as a new user meets it.

Runs `mechsweep run sweeps/quickstart.toml` and `mechsweep plot` in fresh processes, first
with an empty JIT cache (compilation included, as on a clean checkout), then again with the
cache filled. Prints wall times of each step.
"""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _timed(args: list[str], env: dict, cwd: Path) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "mechsweep.cli", *args], env=env, cwd=cwd, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main(scene: str = "sweeps/quickstart.toml") -> dict:
    scene_path = Path(scene).resolve()
    if not scene_path.exists():
        raise FileNotFoundError(f"{scene} does not exist (run from the repository root)")
    from ..scene import load_scene

    load_scene(scene_path)  # an invalid scene is refused here, not as a failed child process
    result = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        env = dict(os.environ, MECHSWEEP_CACHE_DIR=str(tmp / "cache"))
        out = tmp / "quickstart.h5"
        for label in ("cold", "warm"):
            result[f"{label}_run_s"] = _timed(["run", str(scene_path), "-o", str(out), "--no-progress", "--restart"],
                                              env, tmp)
            result[f"{label}_plot_s"] = _timed(["plot", str(out)], env, tmp)
    print(f"mechsweep bench quickstart: {scene} in fresh processes")
    for label, what in (("cold", "empty JIT cache (clean checkout)"), ("warm", "JIT cache filled")):
        run_s, plot_s = result[f"{label}_run_s"], result[f"{label}_plot_s"]
        print(f"  {what:<34}: run {run_s:6.2f} s + plot {plot_s:5.2f} s = {run_s + plot_s:6.2f} s")
    return result
