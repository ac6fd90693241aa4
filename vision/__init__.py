"""ncbot: vision."""
