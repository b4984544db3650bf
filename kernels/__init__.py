"""Generic Warp kernels and functions (imported as ``newton_lab.kernels``).

Grouped by concern: ``context`` (the per-step view a task reads, and its accessors), ``actions`` (action
packing), ``fuse`` (turns a task's declared terms into its step, observation, signal and masked-reset
kernels), ``planner`` (trajectory gather), ``camera`` (view poses, shape colours, segmentation ids),
``runtime`` (Warp settings). Task-specific predicates live with their task; generic ones in
``newton_lab.tasks.common``.
"""
