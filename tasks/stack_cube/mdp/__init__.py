"""StackCube terms."""
