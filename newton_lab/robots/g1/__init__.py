"""Galbot G1: spec (pure data), model building, kinematics, cameras and its registration (``robot.G1``)."""
