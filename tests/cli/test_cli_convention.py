"""Every command follows docs/cli.md. The tests walk the whole Typer app, so a command added tomorrow is checked the
day it is added, and each failure says which command lacks what:

- a command that reports takes `--json`, and then stdout holds exactly one JSON object, seats keyed first / second;
- `--out/-o` is a FOLDER or a FILE and its help says which in the same words; its default is under runs/;
- progress and the MCAP log are turned off by `--no-progress` and `--no-log`, one spelling each;
- a command that writes ends with one line on stderr, `wrote ...`, naming where, and writes nothing else where it
  runs (nothing into the installed package unless asked to by path).
"""
from __future__ import annotations

import inspect
import json
from pathlib import Path
from types import SimpleNamespace
from typing import Any, Callable

import pytest
import typer

from ncbot.pipelines.cli.app import app
from ncbot.pipelines.cli.conventions import JSON_HELP, NO_LOG_HELP, NO_PROGRESS_HELP
from ncbot.pipelines.extras import installed
from tests.cli.conftest import run_main
from tests.learning_helpers import write_tiny_config

ROOT = Path(__file__).resolve().parents[2]


def commands() -> dict[str, Any]:
    """Every leaf command of `ncbot`, by its name after `ncbot` ("train", "logs show", ...)."""
    found = {}

    def walk(command: Any, path: list[str]) -> None:
        for name, sub in getattr(command, "commands", {}).items():
            walk(sub, [*path, name])
        if not hasattr(command, "commands"):
            found[" ".join(path)] = command

    walk(typer.main.get_command(app), [])
    return found


COMMANDS = commands()

#: commands that report nothing a script would read, and why
NOT_REPORTING = {
    "play": "an interactive game in the terminal: its stdout is the conversation",
    "robot serve": "a server that runs until it is stopped; it names its log folder when it starts listening",
}
#: hidden old spellings kept for one release (docs/cli.md), and the spelling that replaces each
RETIRED = {"--progress": "the default", "--no-mcap": "--no-log"}
#: defaults of --out outside runs/, and why
DEFAULT_OUT_ELSEWHERE = {"reproduce": "regenerates the repository's results/ pages (docs/reproduction.md)"}
#: commands with --out that never end (so no `wrote` line)
NEVER_ENDING = {"robot serve": "a server: it names the folder of its logs when it starts listening"}


def options(command: Any) -> list[Any]:
    return [param for param in command.params if param.param_type_name == "option"]


def option(command: Any, spelling: str) -> Any | None:
    return next((o for o in options(command) if spelling in o.opts + o.secondary_opts), None)


def report(problems: list[str]) -> None:
    assert not problems, "commands that break docs/cli.md:\n" + "\n".join(problems)


def test_the_walk_finds_every_area() -> None:
    assert {"train", "eval", "logs show", "vision read", "robot render", "env describe", "reproduce"} <= set(COMMANDS)


def test_every_command_that_reports_takes_json_in_the_same_words() -> None:
    problems = []
    for name, command in COMMANDS.items():
        found = option(command, "--json")
        if name in NOT_REPORTING:
            continue
        if found is None:
            problems.append(f"ncbot {name}: no --json option (add `as_json: bool = json_option()` from "
                            "ncbot.pipelines.cli.conventions, and print the result with print_json)")
        elif found.help != JSON_HELP:
            problems.append(f"ncbot {name} --json: help reads {found.help!r}; use conventions.json_option()")
    report(problems)


def test_out_is_a_folder_or_a_file_and_says_which() -> None:
    problems = []
    for name, command in COMMANDS.items():
        for found in options(command):
            spellings = found.opts + found.secondary_opts
            if "-o" in spellings and "--out" not in spellings or "--output" in spellings:
                problems.append(f"ncbot {name}: {'/'.join(spellings)}; the output option is spelt --out/-o")
            if "--out" not in spellings:
                continue
            kind = {"FOLDER": "Folder for ", "FILE": "File for "}.get(found.metavar)
            if "-o" not in spellings:
                problems.append(f"ncbot {name} --out: no short -o")
            if kind is None or not (found.help or "").startswith(kind):
                problems.append(f"ncbot {name} --out: metavar {found.metavar!r} and help {found.help!r}; use "
                                "conventions.out_folder (several files) or out_file (one file)")
            default = found.default
            if default not in (None, ...) and not str(default).startswith("runs/") and name not in DEFAULT_OUT_ELSEWHERE:
                problems.append(f"ncbot {name} --out: default {str(default)!r} is not under runs/")
    report(problems)


def test_one_spelling_turns_progress_and_the_log_off() -> None:
    problems = []
    for name, command in COMMANDS.items():
        for found in options(command):
            spellings = found.opts + found.secondary_opts
            about = [s for s in spellings if any(word in s for word in ("progress", "mcap", "-log"))]
            if not about:
                continue
            if found.hidden:
                if [s for s in spellings if s not in RETIRED]:
                    problems.append(f"ncbot {name}: hidden option {spellings} is no retired spelling of {RETIRED}")
                continue
            if spellings not in (["--no-progress"], ["--no-log"]):
                problems.append(f"ncbot {name}: {'/'.join(spellings)}; progress and the log are turned off by "
                                "--no-progress and --no-log alone (conventions.no_progress_option, no_log_option)")
            elif found.help not in (NO_PROGRESS_HELP, NO_LOG_HELP):
                problems.append(f"ncbot {name} {spellings[0]}: help reads {found.help!r}; use the conventions' option")
        source = inspect.getsource(command.callback)
        if "progress" in source and option(command, "--no-progress") is None:
            problems.append(f"ncbot {name}: shows progress but takes no --no-progress (conventions.no_progress_option)")
    report(problems)


def reachable_source(function: Callable) -> str:
    """The source of a command and of the functions of its module it calls (its helpers)."""
    import re
    import sys

    source = inspect.getsource(function)
    module = sys.modules[function.__module__]
    helpers = {getattr(module, name, None) for name in re.findall(r"\b(\w+)\(", source)}
    return source + "".join(inspect.getsource(helper) for helper in helpers
                            if inspect.isfunction(helper) and helper is not function)


def test_every_command_that_writes_says_where() -> None:
    problems = [f"ncbot {name}: takes --out but never calls conventions.wrote(...) to end with where it wrote"
                for name, command in COMMANDS.items()
                if option(command, "--out") is not None and name not in NEVER_ENDING
                and "wrote(" not in reachable_source(command.callback)]
    report(problems)


# ------------------------------------------------------------------------------------------------ run every command
@pytest.fixture(scope="module")
def made(tiny_run: Path, tmp_path_factory: pytest.TempPathFactory) -> SimpleNamespace:
    """What the examples read: a finished run with its log, a grid of one tiny run, photos and cell crops."""
    import yaml

    from ncbot.pipelines.cli.app import main

    folder = tmp_path_factory.mktemp("made")
    write_tiny_config(folder)
    grid = folder / "grid.yaml"
    grid.write_text(yaml.safe_dump({"runs_dir": str(folder / "runs"), "suites": {"s": {"standard": {
        "config": "tiny.yaml", "overrides": []}}}, "grid": {"suite": ["s"], "game": ["standard"],
                                                            "agent": ["proposed"], "temporal": [False]}}))
    for kind, name in (("frames", "photos"), ("cells", "cells")):
        with pytest.raises(SystemExit):
            main(["vision", "generate", kind, "--out", str(folder / name), "--n", "2", "--seed", "3"])
    seeds = []  # the run as two seeds of a grid cell, for table and compare
    for seed in range(4):
        seeds.append(folder / "table" / "s" / "standard" / "proposed-temporal" / f"seed{seed}")
        seeds[-1].mkdir(parents=True)
        (seeds[-1] / "config.yaml").write_bytes((tiny_run / "config.yaml").read_bytes())
        result = json.loads((tiny_run / "eval.json").read_text())
        result["run_id"], result["first"]["task_success"] = f"seed{seed}", 0.8 + seed / 20  # two runs, not one copied
        (seeds[-1] / "eval.json").write_text(json.dumps(result))
    episode = json.loads((tiny_run / "eval.json").read_text())["episodes"] - 1
    return SimpleNamespace(run=tiny_run, checkpoint=tiny_run / "checkpoint.pt", grid=grid, photos=folder / "photos",
                           cells=folder / "cells", episode=episode, seeds=seeds, out=None)


def needs(module: str, extra: str) -> None:
    if not installed(module):
        pytest.skip(f"needs the optional extra [{extra}] ({module} is not installed): pip install 'ncbot[{extra}]'")


#: for every command, arguments that run it in seconds (`m`: the `made` fixture; `m.out`: a fresh output path)
EXAMPLES: dict[str, Callable[[SimpleNamespace], list]] = {
    "version": lambda m: ["version"],
    "configs": lambda m: ["configs"],
    "env describe": lambda m: ["env", "describe", "--game", "four"],
    "train": lambda m: ["train", m.grid.parent / "tiny.yaml", "--out", m.out, "collector.total_frames=256",
                        "eval.games=10", "eval.periodic_games=10", "--no-progress"],
    "eval": lambda m: ["eval", m.checkpoint, "--games", "10", "--out", m.out],
    "train-value": lambda m: ["train-value", "--out", m.out, "--positions", "40", "--simulations", "4",
                              "--hidden", "8", "--epochs", "1"],
    "ablate": lambda m: ["ablate", m.grid, "--seeds", "1", "--workers", "1", "--out", m.out,
                         "collector.total_frames=256", "eval.games=10"],
    "table": lambda m: ["table", m.seeds[0].parents[3], "--out", m.out / "table.md"],
    "compare": lambda m: ["compare", *m.seeds[:2], "--against", m.seeds[2], "--against", m.seeds[3], "--out", m.out / "compare.md"],
    "ladder": lambda m: ["ladder", m.checkpoint, "--games", "2", "--opponents", "random", "--out", m.out],
    "match": lambda m: ["match", "random", "rule", "--games", "4"],
    "reproduce": lambda m: ["reproduce", "games-data", m.run, "--out", m.out],
    "logs inspect": lambda m: ["logs", "inspect", m.run],
    "logs episodes": lambda m: ["logs", "episodes", m.run, "--limit", "3"],
    "logs show": lambda m: ["logs", "show", m.run, str(m.episode)],
    "logs acts": lambda m: ["logs", "acts", m.run],
    "logs curve": lambda m: ["logs", "curve", m.run, "--out", m.out / "curve.png"],
    "logs to-rerun": lambda m: needs("rerun", "rerun") or ["logs", "to-rerun", m.run, "--out", m.out / "run.rrd",
                                                           "--max-episodes", "2"],
    "vision read": lambda m: ["vision", "read", m.photos],
    "vision classify": lambda m: ["vision", "classify", m.cells],
    "vision train": lambda m: ["vision", "train", "--out", m.out / "cells.pt", "--cells", "30", "--frames3", "0",
                               "--frames9", "0", "--harsh-cells", "0", "--epochs", "1"],
    "vision eval": lambda m: ["vision", "eval", "--what", "cells", "--out", m.out],
    "vision generate": lambda m: ["vision", "generate", "frames", "--n", "1", "--out", m.out],
    "robot render": lambda m: needs("sapien", "robot") or ["robot", "render", "--frames", "1", "--width", "64",
                                                           "--height", "48", "--out", m.out / "mouth.png"],
    "robot urdf": lambda m: ["robot", "urdf", "--out", m.out / "pepper.urdf"],
}
#: commands not run here, and where they are run
NOT_RUN = {
    "play": "interactive: tests/evaluate/test_play.py plays it in a pseudo-terminal",
    "robot serve": "a server: tests/serve/test_serve.py runs it",
    "robot play": "a SAPIEN game takes about a minute: tests/robot_sim/test_robot_play.py plays one with --json",
    "learn": "needs the log of a robot game: tests/online/test_play_learning.py runs it with --json and reads its "
             "'wrote' line",
}


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_json_is_one_object_and_a_writer_ends_with_where(name: str, made: SimpleNamespace, tmp_path: Path,
                                                         monkeypatch, capfd) -> None:
    if name in NOT_RUN:
        pytest.skip(f"not run here: {NOT_RUN[name]}")
    example = EXAMPLES.get(name)
    assert example is not None, (f"ncbot {name} has no example in tests/cli/test_cli_convention.py EXAMPLES: add "
                                 "arguments that run it in seconds, so its --json and its 'wrote' line are checked")
    where = tmp_path / "here"  # the command runs here: it must write nothing here but what it names
    where.mkdir()
    monkeypatch.chdir(where)
    made.out = tmp_path / "out"
    args = example(made)
    command = COMMANDS[name]
    code, out, err = run_main(capfd, *args, "--json")
    assert code == 0, err
    assert out.count("\n") == 1, f"ncbot {name} --json: stdout holds more than one line:\n{out[:2000]}"
    data = json.loads(out)
    assert isinstance(data, dict), f"ncbot {name} --json: not an object"
    assert not seat_groups(data), f"ncbot {name} --json: seats keyed {seat_groups(data)}; key them first / second"
    assert list(where.iterdir()) == [], f"ncbot {name} wrote {list(where.iterdir())} where it ran"
    if option(command, "--out") is None:
        assert "written" not in data
        return
    last = err.strip().splitlines()[-1]
    assert last.startswith("wrote ") and str(made.out) in last, f"ncbot {name}: its last line is {last!r}"
    assert data.get("written") and all(Path(path).exists() for path in data["written"]), data.get("written")


def seat_groups(data: Any) -> list[str]:
    """Keys that group results by seat under another name than first / second."""
    found = []
    if isinstance(data, dict):
        for key, value in data.items():
            if key in ("seats", "robot_first", "robot_second") and isinstance(value, dict):
                found.append(key)
            found += seat_groups(value)
    elif isinstance(data, list):
        for item in data:
            found += seat_groups(item)
    return found


def test_every_listed_command_exists() -> None:
    """The lists above name real commands (a renamed command must not leave a stale entry behind)."""
    listed = set(EXAMPLES) | set(NOT_RUN) | set(NOT_REPORTING) | set(DEFAULT_OUT_ELSEWHERE) | set(NEVER_ENDING)
    assert listed <= set(COMMANDS), listed - set(COMMANDS)


def test_retired_spellings_still_work_and_stay_hidden(tiny_run: Path, tmp_path: Path, capfd) -> None:
    code, out, err = run_main(capfd, "eval", tiny_run / "checkpoint.pt", "--games", "4", "--progress", "--json")
    assert code == 0 and json.loads(out)["games"] == 4, err
    code, help_text, _ = run_main(capfd, "train", "--help")
    assert code == 0 and "--no-mcap" not in help_text and "--no-log" in help_text
    code, _, err = run_main(capfd, "train", ROOT / "pipelines" / "configs" / "default.yaml", "--no-mcap",
                            "--out", tmp_path / "run", "optim.lr=fast")  # parsed, then stopped by the bad value
    assert code == 2 and "optim.lr" in err and "No such option" not in err
