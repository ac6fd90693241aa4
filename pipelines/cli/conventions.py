"""The options and outputs every command shares, declared once so they read the same everywhere (docs/cli.md).

- `--json`: stdout holds exactly one JSON object, on one line (`print_json`); progress and notes stay on stderr.
- `--out/-o`: where the command writes; a FOLDER when it writes several files, a FILE when it writes one, and the
  help says which in the same words ("Folder for ..." / "File for ...").
- `--no-progress`: no progress on stderr (`ncbot.pipelines.progress.silence`, for every bar of the process).
- `--no-log`: no MCAP episode log.
- A command that writes ends with one line on stderr, `wrote ...`, naming where (`wrote`), so stdout stays the
  result; with `--json` the object lists the same paths under "written".
Light: typer and json only (`ncbot --help` stays fast).
"""
from __future__ import annotations

import json
import math
import os
from typing import Any

import typer

JSON_HELP = "Print one JSON object on stdout instead of the text (progress and notes stay on stderr)."
NO_PROGRESS_HELP = "Show no progress on stderr (by default a bar on a terminal, a line every tenth in a pipe)."
NO_LOG_HELP = "Write no MCAP episode log."
RETIRED_ALIAS_HELP = "Old spelling of {new}, kept for one release."


def _silence_progress(off: bool) -> bool:
    if off:
        from ncbot.pipelines.progress import silence

        silence()
    return off


def json_option() -> Any:
    return typer.Option(False, "--json", help=JSON_HELP)


def no_progress_option() -> Any:
    return typer.Option(False, "--no-progress", help=NO_PROGRESS_HELP, callback=_silence_progress)


def progress_alias() -> Any:
    """`--progress`, the old on-spelling of eval, train-value and robot play (the default anyway): hidden."""
    return typer.Option(True, "--progress", hidden=True, help=RETIRED_ALIAS_HELP.format(new="the default"))


def no_log_option() -> Any:
    return typer.Option(False, "--no-log", help=NO_LOG_HELP)


def out_folder(default: Any, what: str) -> Any:
    """`--out/-o` of a command that writes several files: `what` completes "Folder for ..."."""
    return typer.Option(default, "--out", "-o", metavar="FOLDER", help=f"Folder for {what}")


def out_file(default: Any, what: str) -> Any:
    """`--out/-o` of a command that writes one file (and maybe its companions beside it): "File for ..."."""
    return typer.Option(default, "--out", "-o", metavar="FILE", help=f"File for {what}")


def _plain(value: Any) -> Any:
    """JSON for numpy scalars, paths and non-finite floats (null: JSON has no NaN)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {str(key): _plain(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(item) for item in value]
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if hasattr(value, "tolist"):  # numpy scalars and arrays
        return _plain(value.tolist())
    return value


def print_json(data: dict[str, Any]) -> None:
    """The `--json` output: one object on one line of stdout."""
    typer.echo(json.dumps(_plain(data)))


def wrote(where: str) -> None:
    """The last line of a command that writes: `wrote WHERE` on stderr (stdout keeps the result alone)."""
    typer.echo(f"wrote {where}", err=True)


def listing(paths: list[Any]) -> str:
    """Paths as `a, b and c` for the `wrote` line."""
    names = [os.fspath(path) for path in paths]
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
