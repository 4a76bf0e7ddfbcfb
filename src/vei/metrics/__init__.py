"""vei.metrics."""
