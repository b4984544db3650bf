"""G1 configuration of Reach."""
