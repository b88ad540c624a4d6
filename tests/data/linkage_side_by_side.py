"""Side by side: the four-bar kernel before (hand-written chunk kernel, commit 28a0ab7) and after
(the closed-form model layer's generated kernel), as docs/model-layer.md reports them.

    git archive 28a0ab7 src | tar -x -C /tmp/before
    python tests/data/linkage_side_by_side.py /tmp/before/src src [rounds]

1. Timing: ``rounds`` (default 5) rounds, each running one fresh process per version and thread
   count (1 and 2) that times benchmarks/linkage.py's four-bar residual sweep (``mechsweep_residuals``,
   100,000 designs) 15 times and reports the best and median designs/s. The versions alternate,
   so both see the same background load; the load average is printed with each line.
2. Machine code: with caching off, each version's per-design function fourbar_design is compiled
   and its assembly, with symbol and label names stripped, compared (difflib); ``rounds`` = 0
   skips the timing.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

TIMING = """
import json, sys, time
import numpy as np
try:
    from mechsweep.bench import linkage as bl  # where the bench was in the earlier version
except ImportError:
    from benchmarks import linkage as bl
from mechsweep.execution.execute import threads as _threads
threads = int(sys.argv[1])
P = bl.design_family(100_000, 0)
with _threads(threads):
    bl.mechsweep_residuals(P[:8])
    ts = []
    for _ in range(15):
        t0 = time.perf_counter(); bl.mechsweep_residuals(P); ts.append(time.perf_counter() - t0)
print(json.dumps({"best": P.shape[0] / min(ts), "median": P.shape[0] / float(np.median(ts))}))
"""

ASM = r"""
import re, sys
try:
    from mechsweep.bench import linkage as bl  # where the bench was in the earlier version
except ImportError:
    from benchmarks import linkage as bl
bl.mechsweep_residuals(bl.design_family(16, 0))
try:
    from mechsweep.model import load
    design = [d for k, d in load._JITTED.items() if k[2] == "fourbar_design"][0]
except (ImportError, IndexError):
    from mechsweep.models import _linkage as L
    design = L.fourbar_design
lines = []
for line in "\n".join(design.inspect_asm().values()).splitlines():
    line = re.sub(r"_ZN[\w$.]+", "SYM", line)
    line = re.sub(r"\.LBB\d+_\d+|\.LCPI\d+_\d+|\.Ltmp\d+|\.Lfunc\w+", "LBL", line)
    line = re.sub(r"#.*", "", line).strip()
    if line and not line.startswith("."):
        lines.append(line)
print("\n".join(lines))
"""


def run(src: str, code: str, *args, env=None) -> str:
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # benchmarks/
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([src, root]), **(env or {}))
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, env=env,
                          check=True).stdout


def main(before: str, after: str, rounds: int = 5) -> None:
    for r in range(rounds):
        for label, src in (("before", before), ("after", after)):
            for threads in (1, 2):
                res = json.loads(run(src, TIMING, str(threads)).strip().splitlines()[-1])
                print(f"round {r + 1} {label:6s} {threads} thread(s): best {res['best']:>9,.0f}  median "
                      f"{res['median']:>9,.0f} designs/s  (load average {os.getloadavg()[0]:.2f})", flush=True)
    asm = [run(src, ASM, env={"MECHSWEEP_NO_CACHE": "1"}).splitlines() for src in (before, after)]
    import difflib

    ops = [op for op in difflib.SequenceMatcher(None, asm[0], asm[1], autojunk=False).get_opcodes()
           if op[0] != "equal"]
    print(f"fourbar_design assembly: {len(asm[0])} lines before, {len(asm[1])} after; differences:")
    for tag, i1, i2, j1, j2 in ops:
        for a in asm[0][i1:i2]:
            print(f"  - {a}")
        for b in asm[1][j1:j2]:
            print(f"  + {b}")

if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]) if len(sys.argv) > 3 else 5)
