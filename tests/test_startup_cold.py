"""Start-up of the quickstart commands (issue 15 goal 3): what a warm `mechsweep plot` imports."""
import os
import subprocess
import sys

import mechsweep


def test_plot_does_not_import_dask_and_leaves_xarray_as_it_was(in_tmp, small_duffing):
    """xarray imports dask.array (and with it scipy.fft, 0.4-1 s) to ask whether each new variable is a
    dask array; `mechsweep plot` draws loaded datasets and tells xarray not to ask while it runs
    (cli._no_dask_probe), then puts xarray's own probe back: a dask array made afterwards in the same
    process is still one to xarray."""
    mechsweep.run(small_duffing, output="data/runs/s.h5")
    code = ("import sys; from mechsweep.cli import main; "
            "assert main(['plot', 'data/runs/s.h5', '--kind', 'kinematic_coefficients']) == 0; "
            "from xarray.namedarray import pycompat; "
            "print(sorted(m for m in ('dask.array', 'scipy', 'numba') if m in sys.modules), "
            "'dask' in pycompat._cached_duck_array_modules); "
            "import dask.array as da, xarray as xr; print(xr.DataArray(da.zeros(4, chunks=2)).chunks)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=in_tmp,
                         env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-2:] == ["[] False", "((2, 2),)"]
    assert [p.name for p in (in_tmp / "data/runs").glob("*.png")] == ["s.png"]
