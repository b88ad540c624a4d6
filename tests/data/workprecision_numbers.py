"""The numbers of the work-precision reports (errors, steps, rhs counts, ok fractions, orders,
drift; attributes; never times), recorded with one version of the code and compared with another:
the reports must stay the same numbers when what they measure moves (docs/model-layer.md,
"Work-precision declared by the model").

    python tests/data/workprecision_numbers.py record FILE [small|full]   # with the code before
    python tests/data/workprecision_numbers.py compare FILE [small|full]  # with the code after

small: tests/bench/test_workprecision.py's configuration (6 points, scipy on 3, rtol 1e-5, 1e-8, 1e-11)
and 8 points at N = 12, 45, 360, 1440 for the closed-form models; full: every default. The
models: those the bench names in both versions (duffing, torsional_circuit, autobalancer,
fourbar_balancing, slidercrank_balancing). scipy's rungs past its time budget depend on timing:
a variable is compared where both runs have a value.
"""
import json
import sys
import tempfile

import numpy as np

MODELS = ("duffing", "torsional_circuit", "autobalancer", "fourbar_balancing", "slidercrank_balancing")
TIMED = ("time", "compile", "skipped")


def numbers(config):
    from mechsweep.bench import workprecision as wp

    out = tempfile.mkdtemp()
    res = {}
    for m in MODELS:
        if config == "full":
            ds = wp.main(m, out_dir=out, quiet=True)
        elif m in ("fourbar_balancing", "slidercrank_balancing"):
            from mechsweep.bench import workprecision_linkage as wl
            ds = wl.main(m, points=8, positions=(12, 45, 360, 1440), repeats=1, out_dir=out, quiet=True)
        else:
            ds = wp.main(m, points=6, scipy_points=3, ladder=(1e-5, 1e-8, 1e-11), repeats=1, out_dir=out, quiet=True)
        res[m] = {"vars": {k: [repr(float(x)) for x in np.ravel(ds[k].values)] for k in ds.data_vars
                           if not any(t in k for t in TIMED)},
                  "coords": {c: [str(x) for x in np.ravel(ds[c].values)] for c in ds.coords},
                  "attrs": {k: str(v) for k, v in ds.attrs.items() if not any(t in k for t in TIMED)}}
    return res


def compare(before, after) -> int:
    bad = 0
    for m in MODELS:
        b, a = before[m], after[m]
        for part in ("vars", "coords"):
            for k in sorted(set(b[part]) | set(a[part])):
                x, y = b[part].get(k), a[part].get(k)
                if x is None or y is None or len(x) != len(y):
                    print(f"{m}: {part} {k}: only in one run or different length")
                    bad += 1
                    continue
                both = [(u, v) for u, v in zip(x, y) if "nan" not in (u, v)]
                differ = [(u, v) for u, v in both if u != v]
                print(f"{m}: {k}: {len(both) - len(differ)} of {len(both)} values bitwise"
                      + (f"; DIFFERENT e.g. {differ[0]}" if differ else ""))
                bad += bool(differ)
        for k in sorted(set(b["attrs"]) | set(a["attrs"])):
            if b["attrs"].get(k) != a["attrs"].get(k):
                print(f"{m}: attribute {k}: {b['attrs'].get(k)!r} -> {a['attrs'].get(k)!r}")
    print("same numbers" if not bad else f"{bad} variables differ")
    return 1 if bad else 0


if __name__ == "__main__":
    what, path = sys.argv[1], sys.argv[2]
    config = sys.argv[3] if len(sys.argv) > 3 else "small"
    if what == "record":
        json.dump(numbers(config), open(path, "w"))
    else:
        sys.exit(compare(json.load(open(path)), numbers(config)))
