"""Galbot G1: spec (pure data), model building, action packers."""
