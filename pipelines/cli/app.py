"""The `ncbot` command line: one root Typer app; each area registers its own commands.

Every area module (`env`, `learn`, `grid`, `logs`, `vision`, `robot`, `play`, `reproduce`) exposes
`register(app)` and imports its heavy dependencies (torch, sapien, cv2) inside the commands, so that
`ncbot --help` stays fast. Bad input raises `ValueError`/`FileNotFoundError` with a clear message; `main`
turns it into one line on stderr and exit code 2 (set NCBOT_DEBUG=1 to see the traceback).
"""
from __future__ import annotations

import os
import signal
import sys
import traceback
import warnings

import typer

import ncbot.pipelines.cli.env as cli_env
import ncbot.pipelines.cli.grid as cli_grid
import ncbot.pipelines.cli.learn as cli_learn
import ncbot.pipelines.cli.logs as cli_logs
import ncbot.pipelines.cli.online as cli_online
import ncbot.pipelines.cli.play as cli_play
import ncbot.pipelines.cli.reproduce as cli_reproduce
import ncbot.pipelines.cli.robot as cli_robot
import ncbot.pipelines.cli.vision as cli_vision
from ncbot.pipelines.cli.conventions import json_option, print_json
from ncbot.pipelines.errors import (Terminated, continuation, continue_with, one_line, request_termination,  # light
                                    squeeze)

app = typer.Typer(
    name="ncbot",
    help="ncbot: a Pepper robot that learns to play Noughts & Crosses with people.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def ncbot_version() -> str:
    """The installed package's version, else (a source checkout run as `python -m ncbot`) pyproject's."""
    from importlib.metadata import PackageNotFoundError, version as installed_version
    from pathlib import Path

    try:
        return installed_version("ncbot")
    except PackageNotFoundError:
        import tomllib

        pyproject = Path(__file__).resolve().parents[2] / "pyproject.toml"
        return tomllib.loads(pyproject.read_text(encoding="utf-8"))["project"]["version"]


def _print_version(value: bool) -> None:
    if value:
        typer.echo(f"ncbot {ncbot_version()}")
        raise typer.Exit(0)


@app.callback()
def root(
    _version: bool = typer.Option(False, "--version", callback=_print_version, is_eager=True,
                                  help="Print the ncbot version and exit."),
) -> None:
    """ncbot: a Pepper robot that learns to play Noughts & Crosses with people."""


@app.command()
def version(as_json: bool = json_option()) -> None:
    """Print the ncbot version (as ncbot --version)."""
    if as_json:
        print_json({"version": ncbot_version()})
    else:
        typer.echo(f"ncbot {ncbot_version()}")


for area in (cli_env, cli_learn, cli_online, cli_grid, cli_logs, cli_vision, cli_robot, cli_play, cli_reproduce):
    area.register(app)


def _on_sigterm(_signum: int, _frame: object) -> None:
    request_termination()
    raise Terminated()


def main(args: list[str] | None = None) -> None:
    """Console entry point and the CLI's one error boundary (pipelines/errors.py).

    Usage errors and every expected failure -> one line on stderr, exit 2; Ctrl-C -> one line, exit 130; SIGTERM
    -> one line, exit 143 (both unwind, so atomic writers remove their temp files); a bug -> the traceback and a
    request to report it. NCBOT_DEBUG=1 re-raises expected failures too, to see where they came from.
    """
    click = click_exceptions()

    if threading_is_main():
        signal.signal(signal.SIGTERM, _on_sigterm)
    quiet_library_warnings()
    command = typer.main.get_command(app)
    argv = list(sys.argv[1:] if args is None else args)
    from ncbot.pipelines.progress import silence

    silence(False)  # `--no-progress` of an earlier main() in this process (tests) does not carry over
    continue_with(None)
    code = 0
    try:
        with command.make_context("ncbot", argv) as context:
            command.invoke(context)
    except click.Exit as done:  # --help, typer.Exit(n)
        code = done.exit_code
    except click.NoArgsIsHelpError as usage:
        usage.show()
        code = 2
    except click.ClickException as usage:  # bad option or argument: one line (the usage is under --help)
        where = f" (see: {usage.ctx.command_path} --help)" if getattr(usage, "ctx", None) else ""
        print(f"ncbot: error: {squeeze(usage.format_message())}{where}", file=sys.stderr)
        code = usage.exit_code
    except BrokenPipeError:  # `ncbot configs | head`: the reader left; stop quietly, as a killed writer would
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        code = 141
    except (KeyboardInterrupt, click.Abort):
        print(f"\nncbot: interrupted (Ctrl-C){resume_advice(argv)}", file=sys.stderr)
        code = 130
    except Terminated:
        print(f"ncbot: terminated (SIGTERM){resume_advice(argv)}", file=sys.stderr)
        code = 143
    except Exception as error:  # noqa: BLE001 - the boundary: sorted into expected failures and bugs
        line = one_line(error)
        if line is None or os.environ.get("NCBOT_DEBUG"):
            traceback.print_exc()
            if line is None:
                print("ncbot: internal error (a bug, not your input): please report it with the command you ran "
                      "and the traceback above", file=sys.stderr)
                code = 1
            else:
                code = 2
        if line is not None:
            print(f"ncbot: error: {line}", file=sys.stderr)
            code = 2
    sys.exit(code)


def quiet_library_warnings() -> None:
    """Library warnings that say nothing a user can act on stay off stderr, so a failure's one line stands alone:
    torch on the pickle protocol of a file its safe loader is about to refuse (the refusal is the line), and SAPIEN
    on finding no system Vulkan library or ICD file when imported (a render that then fails says why, in one line)."""
    warnings.filterwarnings("ignore", message="Detected pickle protocol", category=UserWarning)
    warnings.filterwarnings("ignore", category=UserWarning, module=r"sapien(\.|$)")


def resume_advice(argv: list[str]) -> str:
    """What to run to go on after an interrupted command, for the commands whose work can be continued: the command
    a running command named (`ncbot train --resume runs/x`, with its folder), else the same command again."""
    if continuation() is not None:
        return f"; continue with {continuation()}"
    command = next((arg for arg in argv if not arg.startswith("-")), "")
    return {
        "ablate": "; run the same ncbot ablate command again to go on: it skips the finished runs",
        "reproduce": "; run the same ncbot reproduce command again to go on: it skips the finished runs",
    }.get(command, "")


def click_exceptions():
    """The exception classes of the click that typer runs on, through typer's public API only.

    recent typer vendors its own click (the private typer._click), older typer runs on click: either way the
    public `typer.BadParameter` is that click's BadParameter, so ClickException is found on its MRO, and the
    no-arguments help is recognised by its class name, as typer itself does (typer/rich_utils.py).
    """
    import types

    click_exception = next(c for c in typer.BadParameter.__mro__ if c.__name__ == "ClickException")
    no_args = type("NoArgsIsHelpError", (Exception,), {})
    for cls in _subclasses(click_exception):
        if cls.__name__ == "NoArgsIsHelpError":
            no_args = cls
    return types.SimpleNamespace(Exit=typer.Exit, Abort=typer.Abort, ClickException=click_exception,
                                 NoArgsIsHelpError=no_args)


def _subclasses(cls: type) -> list[type]:
    found = []
    for sub in cls.__subclasses__():
        found += [sub, *_subclasses(sub)]
    return found


def threading_is_main() -> bool:
    import threading

    return threading.current_thread() is threading.main_thread()


if __name__ == "__main__":
    main()
