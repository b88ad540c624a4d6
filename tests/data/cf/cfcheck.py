"""Run the CF checker (cfchecker) offline on netCDF files, with the CF tables of this folder.

    python tests/data/cf/cfcheck.py FILE...

prints one JSON object per file: {"file", "version", "counts": {FATAL, ERROR, WARN, INFO},
"messages": ["ERROR variable: text", ...]} (FATAL, ERROR and WARN messages). cfchecker insists on
a ``.nc`` file name: each file is checked through a link named so. The CF version checked is
read from the file's ``Conventions`` (cfchecker's ``--version auto``).

cfchecker's units come from ``cfunits``, which loads the UDUNITS-2 C library with ctypes when it
is imported. When the system has none, the copy the ``cf-units`` wheel ships is used (``UDUNITS``
below: the library and the XML unit database beside it); exit code 3 and a line on stderr when
neither is there.
"""
from __future__ import annotations

import ctypes.util
import gzip
import json
import os
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
TABLES = {"cfStandardNamesXML": "cf-standard-name-table.xml.gz", "cfAreaTypesXML": "area-type-table.xml",
          "cfRegionNamesXML": "standardized-region-list.xml"}


def udunits() -> tuple[str | None, str | None]:
    """(library, XML database) to load: the system's library (its own database), else cf-units'
    copy, else (None, None)."""
    if ctypes.util.find_library("udunits2"):
        return ctypes.util.find_library("udunits2"), None
    try:
        import cf_units
    except ImportError:
        return None, None
    package = Path(cf_units.__file__).resolve().parent
    libs = sorted(package.parent.glob("cf_units.libs/libudunits2*")) + sorted(package.glob(".dylibs/libudunits2*"))
    xml = package / "etc" / "share" / "udunits2.xml"
    return (str(libs[0]), str(xml)) if libs and xml.is_file() else (None, None)


def main(files: list[str]) -> int:
    lib, xml = udunits()
    if lib is None:
        print("no UDUNITS-2 library: neither the system's (libudunits2) nor the cf-units wheel's", file=sys.stderr)
        return 3
    if xml is not None:  # cfunits finds the library by name only: hand it the wheel's copy
        found = ctypes.util.find_library
        ctypes.util.find_library = lambda name: lib if name == "udunits2" else found(name)
        os.environ.setdefault("UDUNITS2_XML_PATH", xml)
    from cfchecker import cfchecks

    with tempfile.TemporaryDirectory() as tmp:
        tables = {}
        for key, name in TABLES.items():
            path = HERE / name
            if name.endswith(".gz"):
                path = Path(tmp) / name[:-3]
                path.write_bytes(gzip.decompress((HERE / name).read_bytes()))
            tables[key] = str(path)
        checker = cfchecks.CFChecker(version=cfchecks.CFVersion(), silent=True, **tables)
        for k, file in enumerate(files):
            link = Path(tmp) / f"{k}.nc"
            link.symlink_to(Path(file).resolve())
            try:
                checker.checker(str(link))
            except cfchecks.FatalCheckerError:
                pass
            results = checker.all_results[str(link)]
            messages = [f"{cat} global: {m}" for cat in ("FATAL", "ERROR", "WARN") for m in results["global"][cat]]
            messages += [f"{cat} {var}: {m}" for var, res in results["variables"].items()
                         for cat in ("FATAL", "ERROR", "WARN") for m in res[cat]]
            counts = {cat: len(results["global"][cat]) + sum(len(r[cat]) for r in results["variables"].values())
                      for cat in ("FATAL", "ERROR", "WARN", "INFO")}
            print(json.dumps({"file": file, "version": str(checker.version), "counts": counts,
                              "messages": messages}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
