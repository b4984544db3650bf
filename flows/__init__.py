"""Prefect flows (imported as newton_lab.flows)."""
