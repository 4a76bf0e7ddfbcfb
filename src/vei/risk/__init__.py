"""Risk as a probability: how likely a collision and an injury are in one encounter,
with 95 % confidence intervals, per planner (``vei risk``, docs/risk.md).

The distribution of one varied quantity is :mod:`vei.config.distributions` (sweeps use it
too). Modules: ``defaults`` (the declared default
variation with sources), ``variation`` (the variation model and its standard space),
``problem`` (an encounter as samples -> simulated outcomes), ``estimators`` (intervals
and diagnostics), ``rare`` (cross-entropy importance sampling, subset simulation:
OpenTURNS), ``assess`` (one planner's figures), ``compare`` (planners on common random
numbers), ``modes`` (failure modes), ``sensitivity`` (Sobol indices: SALib), ``search``
(failure search against pymoo's NSGA-II), ``run`` / ``output`` (``vei risk`` end to
end), ``analytic`` (a scripted problem with a known answer), ``fit`` (the defaults'
figures recomputed from the shared recordings).
"""
