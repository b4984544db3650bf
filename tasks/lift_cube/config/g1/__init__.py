"""G1 configuration of LiftCube: env cfg and motion plan."""
