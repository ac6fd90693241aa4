"""ncbot: pipelines."""
