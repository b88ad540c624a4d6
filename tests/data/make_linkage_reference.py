"""Regenerate tests/data/linkage_reference.npz: the values of the two linkage models
(fourbar_balancing, slidercrank_balancing) as the hand-written chunk kernels computed them,
before the models were rebuilt on the closed-form model layer (issue 13).

Recorded with the code of commit 28a0ab7 (models/_linkage.py fourbar_kernel / slider_kernel):
    PYTHONPATH=src python tests/data/make_linkage_reference.py
except the four-bar's method-2 outputs (axis_*, dM_*_axis, R_axis, the *_h1 ones and their
curves) on the design-grid rows with gravity (g != 0), recorded again when the moved crank
counterweight's weight entered Delta M (models/_linkage.py axis_basis; those kernels left it out,
tests/models/test_linkage_physical.py shows the difference against the mass placed physically): with
the old file, every differing array was one of those outputs of a four-bar grid and every
differing value on a row with g != 0; the shipped scenes' bytes did not change.
tests/models/test_linkage_reference.py recomputes every case with the current code and asks for the
same bytes (a sha256 of each array; the scalar values of the designs' grids are stored too, to
show where a difference is).

Some of those bytes depend on the machine the recording code runs on: run on a 2-core AMD EPYC (Zen 3,
no AVX-512), the code of commit be64218 (which recorded the method-2 outputs) gives other bytes for
six four-bar outputs at 37 crank positions (axis_x, axis_y, dM_rms_axis, dM_max_axis, R_axis,
dM_axis_phi), the same bytes the current code gives there. The cause is not numba's code generation
for the CPU (NUMBA_CPU_NAME=generic gives the same bytes) nor numpy's SIMD loops up to AVX2
(NPY_DISABLE_CPU_FEATURES=X86_V3 neither). The bytes the recording code gives on such a machine are
kept in linkage_reference_alternatives.npz, and the test accepts either:
    PYTHONPATH=<checkout of be64218>/src python tests/data/make_linkage_reference.py --alternatives
records them on the machine it runs on (merged into the file; ``machines`` lists where they were made).

Cases:
- the shipped scenes sweeps/fourbar_*.toml, sweeps/slidercrank_partial.toml and the two extreme
  scenes (sweeps/extreme/fourbar_grashof_limit.toml, slidercrank_toggle.toml), run with
  mechsweep.run: a hash of every stored variable (status included) and every 499th value;
- design grids: random designs of each model (feasible, infeasible and toggling ones, both
  branches, delta != 0, gravity, loads, given counterweights), evaluated through the model's
  ``evaluate`` with all outputs, with each output alone (the kernels skip work by the wanted
  flags: each path once), with the shipped scenes' output lists, and with all outputs at 4, 37
  and 1000 crank positions.
"""
from __future__ import annotations

import hashlib
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
OUT = Path(__file__).resolve().parent / "linkage_reference.npz"
ALTERNATIVES = Path(__file__).resolve().parent / "linkage_reference_alternatives.npz"
SCENES = ("sweeps/fourbar_geometry_family.toml", "sweeps/fourbar_methods.toml", "sweeps/fourbar_pareto.toml",
          "sweeps/slidercrank_partial.toml", "sweeps/extreme/fourbar_grashof_limit.toml",
          "sweeps/extreme/slidercrank_toggle.toml")
SUBSAMPLE = 499
N_DESIGNS = 300
N_CURVE_DESIGNS = 24


def digest(a) -> str:
    a = np.ascontiguousarray(a)
    h = hashlib.sha256(f"{a.dtype.str}{a.shape}".encode())
    h.update(a.tobytes())
    return h.hexdigest()


def fourbar_designs(n: int, seed: int) -> np.ndarray:
    from mechsweep.models import _linkage as L

    rng = np.random.default_rng(seed)
    col = L.FOURBAR_PARAMS.index
    P = np.zeros((n, len(L.FOURBAR_PARAMS)))
    P[:, col("a1")] = rng.uniform(0.05, 0.2, n)
    P[:, col("a2")] = rng.uniform(0.1, 0.6, n)
    P[:, col("a3")] = rng.uniform(0.1, 0.6, n)
    P[:, col("a4")] = rng.uniform(0.25, 0.5, n)
    P[:, col("branch")] = rng.integers(0, 2, n)
    for i in (1, 2, 3):
        P[:, col(f"m{i}")] = rng.uniform(0.2, 3.0, n)
        P[:, col(f"r{i}")] = rng.uniform(0.0, 0.3, n)
        P[:, col(f"theta{i}")] = rng.choice([0.0, 0.0, 0.3, -1.0], n)
        P[:, col(f"I{i}")] = rng.uniform(0.0, 0.05, n)
    P[:, col("omega")] = rng.uniform(5.0, 60.0, n)
    P[:, col("delta")] = rng.choice([0.0, 0.0, 0.3, -0.5], n)
    P[:, col("g")] = rng.choice([0.0, 9.81], n)
    P[:, col("M_load")] = rng.choice([0.0, 2.5], n)
    P[:, col("cw1_mr")] = rng.choice([0.0, 0.1], n)
    P[:, col("cw1_angle")] = rng.uniform(0.0, 2 * math.pi, n)
    P[:, col("r_cw1")] = rng.choice([math.nan, 0.08], n)
    P[:, col("cw3_mr")] = rng.choice([0.0, 0.05], n)
    P[:, col("cw3_angle")] = rng.uniform(0.0, 2 * math.pi, n)
    P[:, col("r_cw3")] = rng.choice([math.nan, 0.1], n)
    # a few special rows: a change-point (toggle) linkage, zero static residual (m2 r2 pendulum)
    P[0, [col("a1"), col("a2"), col("a3"), col("a4")]] = (0.1, 0.2, 0.3, 0.4)  # s + l = p + q: a toggle
    P[1, [col("m1"), col("r1"), col("m3"), col("r3"), col("I1"), col("I3"), col("delta")]] = 0.0
    return P


def slider_designs(n: int, seed: int) -> np.ndarray:
    from mechsweep.models import _linkage as L

    rng = np.random.default_rng(seed)
    col = L.SLIDER_PARAMS.index
    P = np.zeros((n, len(L.SLIDER_PARAMS)))
    r = rng.uniform(0.02, 0.1, n)
    P[:, col("r")] = r
    use_l = rng.integers(0, 2, n).astype(bool)
    lam = rng.uniform(0.1, 1.05, n)
    P[:, col("l")] = np.where(use_l, r / lam, math.nan)
    P[:, col("lam")] = np.where(use_l, math.nan, lam)
    P[:, col("e")] = rng.choice([0.0, 0.0, 0.01, -0.02], n)
    P[:, col("branch")] = rng.integers(0, 2, n)
    for i in (1, 2):
        P[:, col(f"m{i}")] = rng.uniform(0.2, 3.0, n)
        P[:, col(f"r{i}")] = rng.uniform(0.0, 0.1, n)
        P[:, col(f"theta{i}")] = rng.choice([0.0, 0.0, 0.3], n)
        P[:, col(f"I{i}")] = rng.uniform(0.0, 0.01, n)
    P[:, col("m3")] = rng.choice([0.0, 0.5, 1.5], n)
    P[:, col("omega")] = rng.uniform(10.0, 400.0, n)
    P[:, col("delta")] = rng.choice([0.0, 0.0, 0.2], n)
    P[:, col("g")] = rng.choice([0.0, 9.81], n)
    P[:, col("F_load")] = rng.choice([0.0, 100.0], n)
    P[:, col("k")] = rng.uniform(0.0, 1.0, n)
    P[:, col("r_cw")] = rng.choice([math.nan, 0.04], n)
    P[0, [col("m2"), col("m3"), col("r2")]] = (0.5, 0.0, 0.0)  # m_B = 0: F_tb_error_rel SINGULAR
    return P


def evaluate(spec, P, wanted, n_positions):
    from mechsweep import status as st

    n = P.shape[0]
    wanted = spec.closure(wanted)
    out = {o: np.full((n,) + ((n_positions,) if spec.output(o).extra_dims else ()), np.nan) for o in wanted}
    status = np.zeros(n, dtype=st.DTYPE)
    spec.evaluate(P, wanted, None, out, status, np.zeros(n, np.int64), np.zeros(n, np.int64), n_positions)
    return out, status


def scene_outputs(path: str) -> list[str]:
    import tomllib

    return list(tomllib.loads((REPO / path).read_text())["scene"]["outputs"])


def record_scene(path: str, folder) -> dict:
    """Run one shipped scene into ``folder``: {key: hash or sample} of every stored variable."""
    import mechsweep

    data = {}
    ds = mechsweep.run(str(REPO / path), output=str(Path(folder) / (Path(path).stem + ".h5")), progress=False,
                       load=True)
    for name in sorted(ds.data_vars):
        a = ds[name].values
        data[f"scene/{path}/{name}/sha256"] = np.array(digest(a))
        data[f"scene/{path}/{name}/sample"] = a.reshape(-1)[::SUBSAMPLE].copy()
    return data


def record_grid(model: str, data_P=None) -> dict:
    """Every design-grid case of one model (``data_P``: the stored P matrices, else made here)."""
    from mechsweep.models import fourbar_balancing as fb
    from mechsweep.models import slidercrank_balancing as sc

    spec = {"fourbar_balancing": fb.SPEC, "slidercrank_balancing": sc.SPEC}[model]
    if data_P is not None:
        P, Pc = data_P
    elif model == "fourbar_balancing":
        P, Pc = fourbar_designs(N_DESIGNS, 1), fourbar_designs(N_CURVE_DESIGNS, 2)
    else:
        P, Pc = slider_designs(N_DESIGNS, 3), slider_designs(N_CURVE_DESIGNS, 4)
    scenes = [s for s in SCENES if ("fourbar" if model == "fourbar_balancing" else "slider") in s]
    m = spec.name
    data = {f"grid/{m}/P": P, f"grid/{m}/P_curves": Pc}
    scalars = [o.name for o in spec.outputs if not o.extra_dims]
    curves = [o.name for o in spec.outputs if o.extra_dims]
    cases = {"all": (P, scalars, 360), "all_curves": (Pc, scalars + curves, 360)}
    for o in scalars:
        cases[f"alone:{o}"] = (P, [o], 360)
    for o in curves:
        cases[f"alone:{o}"] = (Pc, [o], 360)
    for s in scenes:
        cases[f"scene_outputs:{s}"] = (P, scene_outputs(s), 360)
    for npos in (4, 37, 1000):
        cases[f"positions:{npos}"] = (Pc, scalars + curves, npos)
    for case, (PP, wanted, npos) in cases.items():
        out, status = evaluate(spec, PP, wanted, npos)
        data[f"grid/{m}/{case}/status"] = status
        for o, v in out.items():
            data[f"grid/{m}/{case}/{o}/sha256"] = np.array(digest(v))
            if case == "all":
                data[f"grid/{m}/{case}/{o}"] = v
    return data


def record() -> dict:
    data: dict[str, np.ndarray] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for path in SCENES:
            data.update(record_scene(path, tmp))
    for model in ("fourbar_balancing", "slidercrank_balancing"):
        data.update(record_grid(model))
    return data


def machine() -> str:
    """What the recorded bytes may depend on: numba's target CPU, numpy's SIMD extensions, the BLAS."""
    import llvmlite.binding as llvm

    try:
        from numpy._core._multiarray_umath import __cpu_features__ as features
    except ImportError:  # numpy 1.x
        from numpy.core._multiarray_umath import __cpu_features__ as features
    simd = ",".join(k for k, v in features.items() if v and k.startswith(("AVX", "FMA", "X86")))
    return f"{llvm.get_host_cpu_name()}; numpy {np.__version__} {simd}"


def record_alternatives() -> dict:
    """The hashes of the stored design grids that differ from OUT when the recording code runs on this
    machine, merged into ALTERNATIVES: {key: [hash, ...]} and ``machines``. (The shipped scenes are
    today's files, which an older checkout may not read.)"""
    ref = np.load(OUT)
    data = {}
    for model in ("fourbar_balancing", "slidercrank_balancing"):
        data.update(record_grid(model, (ref[f"grid/{model}/P"], ref[f"grid/{model}/P_curves"])))
    old = dict(np.load(ALTERNATIVES)) if ALTERNATIVES.exists() else {}
    alt = {k: set(map(str, v)) for k, v in old.items() if k != "machines"}
    for k in ref.files:
        if k.startswith("grid/") and k.endswith("sha256") and str(ref[k]) != str(data.get(k)):
            alt.setdefault(k, set()).add(str(data[k]))
    machines = sorted(set(map(str, old.get("machines", []))) | {machine()})
    return {"machines": np.array(machines), **{k: np.array(sorted(v)) for k, v in alt.items()}}


if __name__ == "__main__":
    if "--alternatives" in sys.argv:
        alt = record_alternatives()
        np.savez_compressed(ALTERNATIVES, **alt)
        print(f"wrote {ALTERNATIVES}: {len(alt) - 1} keys with other bytes; machines: {list(alt['machines'])}")
        sys.exit(0)
    data = record()
    if "--check" in sys.argv:
        ref = np.load(OUT)
        bad = [k for k in ref.files if (k.endswith("sha256") and str(ref[k]) != str(data.get(k)))
               or (k.endswith("/status") and not np.array_equal(ref[k], data.get(k)))]
        print(f"{len(bad)} differing of {sum(k.endswith('sha256') for k in ref.files)}: {bad[:10]}")
    else:
        np.savez_compressed(OUT, **data)
        print(f"wrote {OUT} ({OUT.stat().st_size / 1e3:.0f} kB, {len(data)} arrays)")
