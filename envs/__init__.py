"""ncbot: envs."""
