"""ncbot: logs."""
