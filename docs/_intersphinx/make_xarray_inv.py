"""Write xarray.inv: an intersphinx inventory of xarray's public API, made from the installed xarray.

No built inventory of xarray's documentation could be fetched for this folder (see README.md), so
the entries follow the layout of xarray's API reference, where every public name has its own
autosummary page: ``generated/NAME.html#NAME``, e.g. ``generated/xarray.Dataset.sel.html``.

    python docs/_intersphinx/make_xarray_inv.py      # rewrites docs/_intersphinx/xarray.inv
"""
import inspect
import zlib
from pathlib import Path

import xarray as xr

HERE = Path(__file__).resolve().parent


def entries():
    for name in sorted(xr.__all__):
        obj = getattr(xr, name)
        full = f"xarray.{name}"
        if inspect.isclass(obj):
            yield full, "py:class"
            if obj in (xr.Dataset, xr.DataArray):
                for attr in sorted(dir(obj)):
                    if attr.startswith("_"):
                        continue
                    member = inspect.getattr_static(obj, attr)
                    role = "py:property" if isinstance(member, property) else "py:method"
                    yield f"{full}.{attr}", role
        elif callable(obj):
            yield full, "py:function"


def main() -> None:
    lines = [f"{name} {role} 1 generated/{name}.html#$ -" for name, role in entries()]
    header = (f"# Sphinx inventory version 2\n# Project: xarray\n# Version: {xr.__version__}\n"
              "# The remainder of this file is compressed using zlib.\n")
    (HERE / "xarray.inv").write_bytes(header.encode() + zlib.compress(("\n".join(lines) + "\n").encode()))
    print(f"xarray.inv: {len(lines)} entries (xarray {xr.__version__})")


if __name__ == "__main__":
    main()
