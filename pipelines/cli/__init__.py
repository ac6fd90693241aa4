"""The `ncbot` command line: the root app (`ncbot.pipelines.cli.app`) and one module of commands per area."""
