"""vei.export."""
