"""The task API: what a task package declares and may import.

``cfg`` (scene entities, action / observation terms, phases, the ``TaskCfg``), ``compose`` (coherent tasks
from component phases), ``motion_plan`` and ``experts`` (expert declarations as data), ``mimic_cfg`` (Mimic
subtask decompositions). Task terms themselves are ``@wp.func`` over ``newton_lab.kernels.context``.
"""
