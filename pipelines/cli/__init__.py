"""The `ncbot` command line: the root app (`pipelines.cli.app`) and one module of commands per area."""
