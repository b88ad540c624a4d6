"""Developer benchmarks: what the project measures about itself (its speed against the other
tools and its own targets, fixed costs, memory, where the time goes). Not part of the installed
package; run from the repository's root with mechsweep importable (installed, or
``PYTHONPATH=src``)::

    python benchmarks/NAME.py [options]      # or: python -m benchmarks.NAME [options]

``--help`` lists each one's options. What a user runs stays in the package: ``mechsweep bench
workprecision MODEL`` (any model, a user's own included) and ``mechsweep bench duffing`` (the
comparison with the other ODE solvers). docs/performance.md says what each measures.
"""
