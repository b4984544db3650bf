"""LiftCube configurations by robot."""
