"""Robot and prop models shipped as package data (MJCF)."""
