"""Reach terms."""
