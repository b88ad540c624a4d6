"""Generated kernel modules under concurrent first use (dask's threaded scheduler runs chunks of
one scene in several threads, each asking for the scene's kernel at once)."""
from __future__ import annotations

import sys
import threading
import uuid

from mechsweep.model import compile as mc


def test_threads_asking_for_one_generated_module_share_one_import():
    name = "mechsweep_gen_test_" + uuid.uuid4().hex[:12]
    source = "import time\ntime.sleep(0.2)  # a slow import: the threads overlap\nkernel = object()\n"
    got, errors = [], []
    start = threading.Barrier(4)

    def load():
        try:
            start.wait()
            got.append(mc.load_generated(name, source).kernel)
        except Exception as e:  # noqa: BLE001 - any failure is the finding
            errors.append(e)

    threads = [threading.Thread(target=load) for _ in range(4)]
    try:
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    finally:
        (mc._folder() / f"{name}.py").unlink(missing_ok=True)
        sys.modules.pop(name, None)
        mc._LOADED.pop(name, None)
    assert not errors
    assert len(got) == 4 and all(k is got[0] for k in got)  # one module, imported once
    assert not list(mc._folder().glob(f"{name}*.tmp"))
