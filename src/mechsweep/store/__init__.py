"""Datasets on disk and in memory: HDF5 files in netCDF-4's layout, written with h5py directly
(``write.NetCDFWriter``: the objects and attributes h5netcdf would define, with ``_NCProperties``
saying that mechsweep wrote them through h5py), read back by ``xarray.open_dataset(path,
engine="h5netcdf")``; netCDF-C (netCDF4-python, xarray's netcdf4 engine) reads them as well.

- ``journal``: a run's finished chunks, saved one file each as they arrive (crash-safe, resumable),
  and the lock of an output.
- ``write``: what goes into the file and how it is defined (the same code for a dataset in memory).
- ``assemble``: the dataset made from the journal, chunk by chunk (memory bounded by one chunk),
  into a temporary file that replaces the output by one rename, so a finished file is never half
  overwritten; or kept in memory (``MemorySink``).
- ``read``: ``open_dataset``, and the checks of files a run did not write or another process holds.

HDF5 must never see a failed write: after one (disk full, file-size limit, I/O error) the library
is left with an open file it cannot flush, and it crashes the interpreter at exit (exit 139). So
the assembly hands HDF5 a file object (``write.GuardedFile``) that does the writes itself: the
first failure is recorded, and what HDF5 writes after it is kept in memory (at most about one
chunk: the assembly stops at the next chunk), so the library closes its file normally. The file is
then removed and ``WriteFailed`` raised; the journal it was assembled from is untouched.

This package imports nothing of the run (``mechsweep.execution``), the command line or the figures.
"""
from __future__ import annotations

from ..errors import StoreError  # noqa: F401  (mechsweep.store.StoreError, as before the package)
from .read import LOAD_LIMIT_BYTES, open_dataset  # noqa: F401  (mechsweep.store.open_dataset: public)
