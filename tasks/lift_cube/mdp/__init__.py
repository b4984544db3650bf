"""LiftCube terms: predicates (terminations), rewards, observations and reset events."""
