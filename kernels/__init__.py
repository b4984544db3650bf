"""Generic Warp kernels and functions (imported as ``newton_lab.kernels``).

Grouped by concern: ``context`` (the per-step view a task reads), ``actions`` (action packing),
``resets`` (masked resets and seeded randomisation helpers), ``fuse`` (turns a task's declared terms
into single kernels), ``planner`` (trajectory gather). Task-specific predicates live with their task.
"""
