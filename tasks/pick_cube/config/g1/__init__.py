"""G1 configuration of PickCube: env cfg and motion plan."""
