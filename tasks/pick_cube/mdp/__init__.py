"""PickCube terms: predicates (terminations), observations and reset events."""
