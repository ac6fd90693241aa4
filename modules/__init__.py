"""ncbot: modules."""
