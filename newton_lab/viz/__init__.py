"""rerun streaming and replay: ``RerunLogger`` streams a running env (every model shape, body transforms,
per-row scalars, episode events, default blueprint), ``replay_episode`` re-applies a recorded episode's
states and logs them."""

from .blueprint import default_blueprint
from .rerun_log import RerunLogger, replay_episode
from .shapes import log_model_shapes

__all__ = ["RerunLogger", "default_blueprint", "log_model_shapes", "replay_episode"]
