"""Rider calibration: fit the social-force rider to real rider tracks.

- :mod:`vei.calibrate.tracks`: rider and vehicle tracks from the TrafficMonitoring camera
  trajectories (smoothed, resampled at the engine rate, filtered);
- :mod:`vei.calibrate.rollout`: the social-force model simulated along many tracks at once
  (closed-loop windows from recorded states), and the baselines;
- :mod:`vei.calibrate.fit`: per-track fits and pooled vehicle repulsion (scipy.optimize);
- :mod:`vei.calibrate.profile`: the rider profile file (per-track fits + population),
  sampling riders from a population;
- :mod:`vei.calibrate.validate`: leave-one-scenario-out validation table;
- :mod:`vei.calibrate.figures`: speed / acceleration distributions, model vs data.
"""
