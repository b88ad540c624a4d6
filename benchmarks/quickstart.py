"""`python benchmarks/quickstart.py`: the README's main job timed as a new user meets it.

Runs `mechsweep run sweeps/quickstart.toml` and `mechsweep plot` in fresh processes, first
with an empty JIT cache (compilation included, as on a clean checkout), then again with the
cache filled. Prints wall times of each step.
"""
from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):  # run as `python benchmarks/NAME.py`: import from the repository's root, as -m does
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import os
import subprocess
import tempfile
import time


def _timed(args: list[str], env: dict, cwd: Path) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "mechsweep.cli", *args], env=env, cwd=cwd, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main(scene: str = "sweeps/quickstart.toml") -> dict:
    scene_path = Path(scene).resolve()
    if not scene_path.exists():
        raise FileNotFoundError(f"{scene} does not exist (run from the repository root)")
    from mechsweep.scene import load_scene

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
    print(f"benchmarks/quickstart.py: {scene} in fresh processes")
    for label, what in (("cold", "empty JIT cache (clean checkout)"), ("warm", "JIT cache filled")):
        run_s, plot_s = result[f"{label}_run_s"], result[f"{label}_plot_s"]
        print(f"  {what:<34}: run {run_s:6.2f} s + plot {plot_s:5.2f} s = {run_s + plot_s:6.2f} s")
    return result


def cli(argv: list[str] | None = None) -> int:
    """``python benchmarks/quickstart.py [--scene S]``."""
    from benchmarks import _cli

    p = _cli.parser("quickstart", "time the quickstart (run + plot) in fresh processes, cold and warm JIT cache")
    p.add_argument("--scene", default="sweeps/quickstart.toml", help="the quickstart scene (default sweeps/quickstart.toml)")

    def command(a) -> int:
        main(a.scene)
        return 0

    return _cli.run(p, command, argv)


if __name__ == "__main__":
    sys.exit(cli())
