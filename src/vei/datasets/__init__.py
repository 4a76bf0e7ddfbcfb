"""vei.datasets."""
