"""vei.report."""
