"""vei.experiments."""
