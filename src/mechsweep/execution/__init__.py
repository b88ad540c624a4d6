"""Running a scene: the plan, the chunks computed here or on a dask cluster, the route to a sink.

- ``plan``: Scene -> Plan, what a run computes and how, decided once before any chunk.
- ``execute``: ``evaluate_chunk``, the one function a local run and a dask worker both call; the
  compile phase; the local loop over a run's chunks.
- ``cluster``: the chunks as tasks on a dask.distributed cluster.
- ``runner``: ``run`` and ``compute`` (``mechsweep.run``, ``mechsweep.compute``), the one route from
  a plan to a sink (the journal and the dataset's file, or memory).
- ``checks``: what a run checks before it writes anything; ``stopping``: signals, and what a run
  that stops says and keeps; ``progress``: the progress bar or log lines; ``provenance``: the
  attributes a dataset starts with.

The package is not named ``run``: ``mechsweep.run`` is the public function, and importing a
submodule ``mechsweep.run`` would replace that attribute of the package by the module (the same
holds for ``compute``, hence ``execute``). The journal and the files a run writes are the store's
(``mechsweep.store``), which imports nothing from here.
"""
