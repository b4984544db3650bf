"""G1 configuration of StackCube."""
