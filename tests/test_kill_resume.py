"""A run killed with SIGKILL mid-way resumes to a dataset identical to an uninterrupted run."""
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import mechsweep
from mechsweep.journal import partial_path

SCENE = """
[scene]
name = "kill"
model = "duffing"
outputs = ["period", "period_error", "v_max"]
[axes]
A = {{ start = 0.01, stop = 1.0, num = {n_a} }}
mu = {{ start = 1e-3, stop = 1e3, num = 200, spacing = "log" }}
[fixed]
omega = 1.0
[storage]
chunk_size = 2000
"""


def chunks_done(part) -> int:
    try:
        return sum(1 for p in (part / "chunks").iterdir() if p.suffix == ".npz")
    except FileNotFoundError:  # not created yet
        return -1


@pytest.mark.parametrize("kill_after", [1, 7])
def test_sigkill_then_resume_is_identical(in_tmp, kill_after):
    (in_tmp / "kill.toml").write_text(SCENE.format(n_a=1000))
    out = in_tmp / "data" / "runs" / "k.h5"
    part = partial_path(out)
    proc = subprocess.Popen([sys.executable, "-m", "mechsweep.cli", "run", "kill.toml", "-o", str(out),
                             "--no-progress", "--threads", "1"], cwd=in_tmp,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    while chunks_done(part) < kill_after and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert part.exists() and not out.exists(), "the run finished before it could be killed"
    resumed = subprocess.run([sys.executable, "-m", "mechsweep.cli", "run", "kill.toml", "-o", str(out),
                              "--no-progress", "--resume"], cwd=in_tmp, capture_output=True, text=True)
    assert resumed.returncode == 0, resumed.stderr
    reference = mechsweep.run(mechsweep.load_scene(in_tmp / "kill.toml"), output=in_tmp / "ref.h5", progress=False)
    done = mechsweep.open_dataset(out)
    for name in ("period", "period_error", "v_max", "status", "n_steps", "n_rhs", "A", "mu"):
        np.testing.assert_array_equal(done[name].values, reference[name].values, err_msg=name)
