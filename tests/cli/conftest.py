"""A small trained run with its MCAP log, shared by the CLI tests, and `run_main`: a command run in this process
(the CLI's own `main`, its error boundary included) with what it printed on stdout and stderr."""
from __future__ import annotations

from pathlib import Path

import pytest

from tests.learning_helpers import write_tiny_config


def run_main(capfd: pytest.CaptureFixture, *args: str | Path) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of `ncbot ARGS` run through `ncbot.pipelines.cli.app.main`."""
    from ncbot.pipelines.cli.app import main

    capfd.readouterr()
    try:
        main([str(arg) for arg in args])
        code = 0
    except SystemExit as done:
        code = done.code or 0
    out, err = capfd.readouterr()
    return code, out, err


@pytest.fixture(scope="session")
def tiny_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A finished 3x3 run of a few hundred frames, logged to MCAP (checkpoint.pt, eval.json, episodes-*.mcap)."""
    from ncbot.pipelines.config import load_config
    from ncbot.pipelines.train.run import train

    folder = tmp_path_factory.mktemp("tiny")
    config = load_config(write_tiny_config(folder, logger={"mcap": True, "progress": False}))
    train(config, folder / "run")
    return folder / "run"
