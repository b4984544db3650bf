"""Robot descriptions: pure-data specs, model building and action packers."""
