"""vei.sim.backends."""
