"""Batched motion-plan execution: the agent that runs a task's ``MotionPlan`` (``newton_lab.task_api.motion_plan``)."""
