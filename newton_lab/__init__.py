"""newton_lab: robot learning on NVIDIA Warp and Newton."""

from .kernels import runtime as _warp_runtime

_warp_runtime.install()  # Warp quiet from its import on (NEWTON_LAB_VERBOSE=1 keeps its output)
