"""Batched motion-plan execution: plans (``plan``) and the agent that runs them (``agent``)."""
