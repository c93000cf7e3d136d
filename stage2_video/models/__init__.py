"""Stage-2 appearance models (pose map -> frame of the target person)."""
