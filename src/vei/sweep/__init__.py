"""Sweeps: many variants of one or more scenarios through the batched engine.

- :mod:`vei.sweep.spec`: the sweep file (design, parameters, ranges) -> :class:`SweepSpec`;
  :mod:`vei.sweep.params`: a design's variants table -> engine parameters.
- :mod:`vei.sweep.run`: :func:`run_sweep` (resumable, chunked, parallel) and its results;
  :mod:`vei.sweep.runners`, :mod:`vei.sweep.workers`: local processes or Ray;
  :mod:`vei.sweep.evaluator`: one chunk through the engine; :mod:`vei.sweep.ids`: variant
  ids and seeds; :mod:`vei.sweep.io`: parts, results and run configs on disk.
- :mod:`vei.sweep.critical`: the most critical variants recorded in full;
  :mod:`vei.sweep.compare`: policies against the reference on the same variants;
  :mod:`vei.sweep.riskmap`: risk and severity maps over two parameters.
"""
