"""vei.maps."""
