"""vei.sim."""
