"""What a PPO actor observes: the task's observation vector, and optionally the commanded joints' state.

Under ``joint_mode="delta"`` an action moves each arm joint's target from where it is, and the drive pulls the joint
toward that target; the task's observation holds the joints' positions but neither their velocities nor the targets,
so the actor cannot tell how far a joint lags its target (an arm holding a cube against gravity, fingers squeezing
it). ``joint_state=True`` appends, per action column, the joint's velocity [rad/s | m/s] and the current target
(``env.current_action()``: the target of absolute and gripper columns, 0 for relative and wheel-speed ones), as
IsaacLab's and ManiSkill's manipulation policies observe joint velocities. Training (``RslRlVecEnv``) and evaluation
(``RLPolicyAgent``) build the vector with this one class.
"""

from __future__ import annotations

import torch
import warp as wp


class PolicyObservation:
    """``obs()``: (num_envs, dim) the actor's input for ``env``'s current state."""

    def __init__(self, env, joint_state: bool = False) -> None:
        self.env = env
        self.joint_state = bool(joint_state)
        names = env.action_joint_names if self.joint_state else []
        self._dofs = torch.tensor(env.joints.dofs(names), dtype=torch.long, device=env.torch_device)
        self.dim = int(env.obs.shape[1]) + (2 * env.action_dim if self.joint_state else 0)

    def __call__(self) -> torch.Tensor:
        """A new tensor (not a view of the env's buffers, which the next step overwrites)."""
        env = self.env
        if not self.joint_state:
            return env.obs.clone()
        qd = wp.to_torch(env.state.joint_qd).view(env.num_envs, -1).index_select(1, self._dofs)
        return torch.cat([env.obs, qd, env.current_action()], dim=1)
