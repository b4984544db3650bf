"""``env.sensors.images``: the env's image observations by name, a mapping that renders on first read."""

from __future__ import annotations

from collections.abc import Iterator, Mapping

import torch


class ImageViews(Mapping):
    """``env.sensors.images``: image observations by name, rendered on first read after each step or reset."""

    def __init__(self, cameras):
        """``cameras``: the env's ``envs.cameras.Cameras``, which renders them."""
        self._cameras = cameras

    def __getitem__(self, name: str) -> torch.Tensor:
        if name not in self._cameras.terms:
            if not self._cameras.specs:
                raise KeyError(
                    f"image term {name!r} needs cameras, but this env renders none (a state-only task or "
                    f"make_env(..., cameras=False)); build the env with its task's cameras"
                )
            raise KeyError(f"no image term {name!r}; this env's image terms are {list(self._cameras.terms)}")
        return self._cameras.render()[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._cameras.terms)

    def __len__(self) -> int:
        return len(self._cameras.terms)

    def __contains__(self, name: object) -> bool:
        return name in self._cameras.terms
