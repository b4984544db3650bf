"""rerun streaming and replay: ``RerunLogger`` streams a running env, ``replay_episode`` re-applies a
recorded episode's states and logs them."""

from .rerun_log import RerunLogger, replay_episode

__all__ = ["RerunLogger", "replay_episode"]
