"""newton_lab: robot learning on NVIDIA Warp and Newton."""
