"""The auto-balancer's sample instants, old kernel against the layer (docs/model-layer.md, "Why
residual_amplitude stays 1 ulp off"): the hand-written kernel's grid (linspace in tau, merged in
tau: tests/reference/autobalancer_kernels.sample_grid) against the layer's (linspace in forcing periods s,
merged in s, t = T s: model/trajectory.grid) and against the layer's rows with each part's
instants computed in time with the old association (linspace(f0 (T E), T E, n)), for Kick +
Steady + the re-check's whole periods at the model's default settings and several horizons.

    python tests/data/sample_instants.py
"""
import math
import sys
from pathlib import Path

import numpy as np

from mechsweep.engine import sampling as tr
from mechsweep.model.sampled import Kick, Steady
from mechsweep.models import autobalancer as ab

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository root: tests.reference
from tests.reference import autobalancer_kernels as K  # noqa: E402


def main():
    T = ab.forcing_period(None)
    for H in (7.0, 20.0, 33.3, 300.0, 1000.0):
        settings = {x.name: x.default for x in ab.MODEL.settings}
        settings["horizon_revolutions"] = H
        old = K.sample_grid(settings, False)[0]
        chosen = [m for m in ab.MODEL.measurements if isinstance(m, (Steady, Kick))]
        s, _, _ = tr.grid(chosen, settings)
        whole = np.arange(math.ceil(0.5 * H), math.floor(H) + 1, dtype=np.float64)
        s = np.unique(np.concatenate([s, whole]))
        times = {}
        for m in chosen:
            for x, _ in m.instants(settings):
                E = x[-1]
                for sv, tv in zip(x, np.linspace(x[0] / E * (T * E), T * E, x.size)):
                    times.setdefault(sv, tv)
        for sv in whole:
            times.setdefault(sv, T * sv)
        timed = np.array([times[v] for v in s])
        if s.size == old.size:
            print(f"H = {H:g}: {old.size} instants in both; T s differs from the old at {int((T * s != old).sum())}, "
                  f"the per-part time arithmetic at {int((timed != old).sum())}")
        else:
            close = np.flatnonzero(np.diff(old) <= 4 * np.spacing(old[1:]))
            pairs = ", ".join(f"{float(old[i])!r} and {float(old[i + 1])!r} (s = {old[i] / T:g})" for i in close[:3])
            print(f"H = {H:g}: the row sets differ: {old.size} instants merged in tau, {s.size} rows merged in s"
                  + (f"; instants within 4 ulp in tau: {pairs}" if pairs else ""))


if __name__ == "__main__":
    main()
