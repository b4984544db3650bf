"""Robot descriptions: pure-data specs, model building, the robot binding and its registry."""
