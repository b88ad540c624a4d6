"""`mechsweep boundaries SCENE`: locate the boundaries a scene's [boundaries] section asks for."""
from __future__ import annotations

import sys

BOUNDARIES_DESCRIPTION = """\
Locate where a criterion crosses its level (or the status changes) along one axis, for every
combination of the other axes: bracketed on the scene's grid (computed first, or completed,
unless its dataset is finished), refined to [boundaries] rtol. Writes NAME.boundaries.h5 beside
the grid's dataset NAME.h5 (atomically; the dataset is only read); `mechsweep plot NAME.h5` draws
them over the charts. See docs/boundaries.md.

examples:
  mechsweep boundaries sweeps/autobalancer_stability_chart.toml
  mechsweep boundaries sweeps/autobalancer_stability_chart.toml --data /tmp/chart.h5 -o /tmp/b.h5
"""


def add_parser(sub, fmt) -> None:
    p = sub.add_parser("boundaries", help="locate the boundaries a scene's [boundaries] section asks for",
                       formatter_class=fmt, description=BOUNDARIES_DESCRIPTION)
    p.add_argument("scene", metavar="SCENE", help="scene TOML file with a [boundaries] section")
    p.add_argument("-o", "--output", metavar="PATH", help="output file (default: NAME.boundaries.h5 beside the dataset NAME.h5)")
    p.add_argument("--data", metavar="DATA", help="the grid's dataset (default: [storage] path of the scene)")
    p.add_argument("--threads", type=int, metavar="N", help="numba threads (default: all cores)")
    p.add_argument("--no-progress", action="store_true", help="do not show the progress bar of the grid")
    p.set_defaults(func=command)


def command(args) -> int:
    from ..boundaries import BAND_EDGE, BOUND_MEANINGS, run_boundaries, warnings_for
    from ..scene import load_scene

    scene = load_scene(args.scene)
    for text in warnings_for(scene):
        print(f"mechsweep boundaries: warning: {text}", file=sys.stderr)
    path, ds = run_boundaries(scene, data=args.data, output=args.output, threads=args.threads,
                              progress=False if args.no_progress else None, warn=False)
    bound = ds["boundary_bound"].values
    counts = {BOUND_MEANINGS[c]: int((bound == c).sum()) for c in sorted(BOUND_MEANINGS) if (bound == c).any()}
    print(f"wrote {path}: {ds.attrs['located']} boundaries located along {ds.attrs['along']} ({counts}); "
          f"{ds.attrs['evaluations_per_point_mean']:.1f} evaluations per point (max "
          f"{ds.attrs['evaluations_per_point_max']}) in {ds.attrs['evaluate_calls']} calls, "
          f"{ds.attrs['wall_time_s']:.2f} s")
    if "curve_stop" in ds:
        stops = ds["curve_stop"].values
        print(f"  continued in {ds.attrs['continue_in']}: {int((stops >= 0).sum())} curve(s), "
              f"{int((ds['fold_axis'].values >= 0).sum())} fold(s), {ds.attrs['continuation_evaluated_points']:,} points "
              f"in {ds.attrs['continuation_calls']:,} calls, {ds.attrs['continuation_wall_time_s']:.2f} s")
        if (edges := int((bound == BAND_EDGE).sum())):
            print(f"  {edges} band edge(s) not continued: the criterion stays at its level on one side (a neutral "
                  "stretch), so there is no crossing to follow; a little damping makes it cross (docs/boundaries.md)")
    return 0
