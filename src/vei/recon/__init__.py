"""vei.recon."""
