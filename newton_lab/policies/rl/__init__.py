"""Reinforcement learning on the batched envs: PPO through rsl_rl (``train``), the env as rsl_rl's ``VecEnv``
(``vec_env``), how PPO's actions map onto the env's columns (``actions``), and the trained actor as an agent
(``agent``). Only ``train`` and ``vec_env`` import rsl_rl; running a checkpoint needs torch alone."""
