"""The `ncbot` command line: one root Typer app; each area registers its own commands.

Every area module (`cli_env`, `cli_learn`, `cli_logs`, `cli_vision`, `cli_robot`, `cli_play`) exposes
`register(app)` and imports its heavy dependencies (torch, sapien, cv2) inside the commands, so that
`ncbot --help` stays fast. Bad input raises `ValueError`/`FileNotFoundError` with a clear message; `main`
turns it into one line on stderr and exit code 2 (set NCBOT_DEBUG=1 to see the traceback).
"""
from __future__ import annotations

import os
import sys

import typer

from pipelines import cli_env, cli_learn, cli_logs, cli_play, cli_reproduce, cli_robot, cli_vision

app = typer.Typer(
    name="ncbot",
    help="ncbot: a Pepper robot that learns to play Noughts & Crosses with people.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)



@app.callback()
def root() -> None:
    """ncbot: a Pepper robot that learns to play Noughts & Crosses with people."""


@app.command()
def version() -> None:
    """Print the installed ncbot version."""
    from importlib.metadata import version as installed_version

    typer.echo(f"ncbot {installed_version('ncbot')}")


for area in (cli_env, cli_learn, cli_logs, cli_vision, cli_robot, cli_play, cli_reproduce):
    area.register(app)


def main() -> None:
    """Console entry point: run the app, turning input errors into one line and exit code 2."""
    try:
        app(standalone_mode=True)
    except (ValueError, FileNotFoundError, IsADirectoryError, NotADirectoryError) as error:
        if os.environ.get("NCBOT_DEBUG"):
            raise
        print(f"ncbot: error: {error}", file=sys.stderr)
        sys.exit(2)


if __name__ == "__main__":
    main()
