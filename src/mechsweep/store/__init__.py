"""Datasets on disk and in memory: HDF5 files in netCDF-4's layout, written with h5py directly
(``write.NetCDFWriter``, ``_NCProperties`` saying so), read by xarray's h5netcdf engine and by
netCDF-C. ``journal``: a run's finished chunks (crash-safe, resumable) and the lock of an output;
``write``: what goes into the file and how it is defined (the same code for a dataset in memory);
``assemble``: the dataset from the journal into a temporary file that replaces the output by one
rename, or kept in memory (``MemorySink``); ``read``: ``open_dataset`` and the checks of files a
run did not write or another process holds.

HDF5 must never see a failed write: after one (disk full, I/O error) the library keeps an open
file it cannot flush and crashes the interpreter at exit (exit 139). So the assembly hands HDF5 a
file object (``write.GuardedFile``) that does the writes itself: the first failure is recorded,
what HDF5 writes after it is kept in memory (about one chunk at most), the library closes its
file normally, and the file is removed and ``WriteFailed`` raised; the journal is untouched.

This package imports nothing of the run (``mechsweep.execution``), the command line or the figures.
"""
from __future__ import annotations

from ..errors import StoreError  # noqa: F401  (mechsweep.store.StoreError, as before the package)
from .read import LOAD_LIMIT_BYTES, open_dataset  # noqa: F401  (mechsweep.store.open_dataset: public)
