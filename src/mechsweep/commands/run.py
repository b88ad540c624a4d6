"""`mechsweep run SCENE`: compute a scene's grid into its dataset (``mechsweep.compute``)."""
from __future__ import annotations

import sys

RUN_EPILOG = """\
The grid is cut into chunks; each finished chunk is saved at once to the journal PATH.partial/
(a kill leaves every chunk file whole or absent). When every chunk is in, the dataset is
assembled and renamed to PATH, so an existing PATH is never left half overwritten. If the run is
interrupted (Ctrl-C, kill, power cut), `--resume` computes only the missing chunks; the result is
identical to an uninterrupted run. A second run on the same PATH is refused while one is writing.
SIGTERM stops a run like Ctrl-C (exit 143). A failed write (disk full, ulimit -f, quota, I/O error)
ends it with a message and exit 2, the journal kept for --resume; a damaged chunk file in the
journal is removed and computed again.
An existing PATH is replaced by a run of the same scene; a dataset of a different scene, or a file
mechsweep did not write, is kept and the run refused unless --overwrite. PATH, its lock
.PATH.lock and its journal must be regular files and folders (not pipes, sockets or devices).

With --scheduler (or [execution] scheduler in the scene) the chunks run as tasks on a
dask.distributed cluster (pip install "mechsweep[distributed]"); this process still writes the
file, and the result is the same as a local run, bit for bit.

examples:
  mechsweep run sweeps/duffing_amplitude_period.toml
  mechsweep run sweeps/duffing_amplitude_period.toml -o /tmp/ap.h5 --threads 1
  mechsweep run sweeps/duffing_amplitude_period.toml --resume
  mechsweep run sweeps/duffing_amplitude_period.toml --scheduler tcp://10.0.0.5:8786
"""


def add_parser(sub, fmt) -> None:
    p = sub.add_parser("run", help="compute a scene's grid into an HDF5 dataset", description=RUN_EPILOG,
                       formatter_class=fmt)
    p.add_argument("scene", metavar="SCENE", help="scene TOML file, e.g. sweeps/quickstart.toml")
    p.add_argument("-o", "--output", metavar="PATH", help="output file (default: [storage] path of the scene)")
    p.add_argument("--resume", action="store_true", help="complete an interrupted run of the same scene")
    p.add_argument("--restart", action="store_true", help="discard an unfinished run and start over")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing PATH that holds a run of a different scene, or a file mechsweep "
                        "did not write (refused without it; re-running the same scene needs no flag)")
    p.add_argument("--threads", type=int, metavar="N",
                   help="numba threads (default: all cores); with --scheduler, per dask worker")
    p.add_argument("--no-progress", action="store_true", help="do not show the progress bar")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run the chunks on this dask.distributed scheduler, e.g. tcp://10.0.0.5:8786 "
                        "(default: the scene's [execution] scheduler, else local threads)")
    p.add_argument("--worker-timeout", type=float, metavar="SECONDS",
                   help="with --scheduler: stop (journal kept) when the scheduler is lost or has no worker "
                        "for this long (default: the scene's [execution] worker_timeout, else 120)")
    p.set_defaults(func=command)


def command(args) -> int:
    from ..errors import RunInterrupted
    from ..execution.runner import compute
    from ..scene import load_scene
    from . import started

    scene = load_scene(args.scene)
    started()
    try:  # the dataset is not opened: its status counts were added up as its chunks were assembled
        summary = compute(scene, output=args.output, resume=args.resume, restart=args.restart,
                          threads=args.threads, progress=False if args.no_progress else None,
                          scheduler=args.scheduler, worker_timeout=args.worker_timeout,
                          overwrite=args.overwrite)
    except RunInterrupted as exc:
        print(f"mechsweep run: {exc}", file=sys.stderr)
        return 128 + exc.signum
    print(f"wrote {summary.path.resolve()}: {summary.sizes}, outputs {', '.join(scene.outputs)}; "
          f"status {summary.status_names()}; wall time {summary.wall_time_s:.2f} s "
          f"(compile {summary.compile_time_s:.2f} s, compute {summary.compute_time_s:.2f} s)")
    return 0
