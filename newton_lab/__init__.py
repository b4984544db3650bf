"""newton_lab: robot learning on NVIDIA Warp and Newton."""

from .kernels import runtime as _warp_runtime

_warp_runtime.install()  # Warp without adjoint kernels and quiet, from its import on (kernels/runtime.py)
