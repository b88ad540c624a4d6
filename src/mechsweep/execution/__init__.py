"""Running a scene: ``plan`` (Scene -> Plan), ``execute`` (``evaluate_chunk``, the one function a
local run and a dask worker both call; the compile phase; the local loop), ``cluster`` (dask),
``runner`` (``mechsweep.run`` and ``mechsweep.compute``: the one route from a plan to a sink),
``checks`` (before anything is written), ``stopping`` (signals; what a stopped run says and keeps),
``progress`` and ``provenance``.

Not named ``run`` (nor ``compute``, hence ``execute``): importing a submodule of that name would
replace the public function ``mechsweep.run`` by the module. The files a run writes are the
store's (``mechsweep.store``), which imports nothing from here."""
