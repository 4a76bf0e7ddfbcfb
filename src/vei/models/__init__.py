"""vei.models."""
