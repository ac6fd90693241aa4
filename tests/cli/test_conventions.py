"""The command line follows one convention (docs/cli.md): who opens is `--first`, a checkpoint is a positional
CHECKPOINT, a cell is written b2, `ncbot --version` works, and the rough edges each stop with one line naming what to
do (the options every command shares: tests/cli/test_cli_convention.py)."""
from __future__ import annotations

import json
import tomllib
from pathlib import Path

import pytest
import torch
import yaml

from ncbot.pipelines.checkpoint import FORMAT, atomic_save
from ncbot.pipelines.config import RunConfig
from tests.learning_helpers import ncbot

ROOT = Path(__file__).resolve().parents[2]


def one_line_error(result, *needles: str) -> str:
    """Exit 2 and one line on stderr holding every needle; returns the line."""
    err = result.stderr.strip()
    assert result.returncode == 2, result.stdout + result.stderr
    assert len(err.splitlines()) == 1 and err.startswith("ncbot: error:"), err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in err, err
    return err


def agent_checkpoint(path: Path, game: str = "standard") -> Path:
    """A small but valid agent checkpoint of `game` (zero weights: enough to load and to read its game)."""
    config = RunConfig.model_validate({"agent": {"hidden": [8]}, "env": {"game": game}})
    features, actions = (73, 18) if game == "standard" else (None, None)
    if game != "standard":
        from ncbot.envs import make_env

        env = make_env(game)
        features, actions = env.n_features, env.n_actions
    widths = [features, 8, actions]
    qnet = {}
    for layer, (inputs, outputs) in enumerate(zip(widths, widths[1:])):
        qnet[f"module.{2 * layer}.weight"] = torch.zeros(outputs, inputs)
        qnet[f"module.{2 * layer}.bias"] = torch.zeros(outputs)
    atomic_save({"format": FORMAT, "config": config.to_dict(), "n_features": features, "n_actions": actions,
                 "qnet": qnet}, path)
    return path


# ------------------------------------------------------------------------------------------------ --version
def test_version_prints_the_package_version() -> None:
    expected = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    for args in (["--version"], ["version"]):
        result = ncbot(*args)
        assert result.returncode == 0, result.stderr
        assert result.stdout.strip() == f"ncbot {expected}"


# ------------------------------------------------------------------------------------------------ one name each
@pytest.mark.parametrize("command,old", [
    (["eval", "CKPT", "--seat", "first"], "--seat"),
    (["play", "--seat", "first"], "--seat"),
    (["robot", "play", "--starts", "human"], "--starts"),
    (["play", "--checkpoint", "CKPT"], "--checkpoint"),
    (["robot", "play", "--checkpoint", "CKPT"], "--checkpoint"),
    (["robot", "serve", "--checkpoint", "CKPT"], "--checkpoint"),
    (["eval", "CKPT", "--mcap", "DIR"], "--mcap"),
    (["play", "--log-dir", "DIR"], "--log-dir"),
    (["logs", "curve", "DIR", "--output", "c.png"], "--output"),
    (["robot", "render", "--output", "m.png"], "--output"),
    (["vision", "generate", "frames", "--out", "DIR", "--conditions", "harsh"], "--conditions"),
])
def test_old_spellings_are_unknown_options(command: list[str], old: str) -> None:
    one_line_error(ncbot(*command), f"No such option: {old}")


def test_checkpoint_is_positional_and_says_what_it_expects(tmp_path: Path) -> None:
    config = tmp_path / "config.yaml"
    config.write_text("env: {game: standard}\n")
    for command in (["eval"], ["ladder"], ["robot", "play"]):
        one_line_error(ncbot(*command, str(config)), "is not a checkpoint", "expected a checkpoint .pt or a run folder")
    empty = tmp_path / "empty_run"
    empty.mkdir()
    one_line_error(ncbot("eval", str(empty)), "holds no checkpoint.pt")


def test_the_game_is_read_from_the_checkpoint(tmp_path: Path) -> None:
    from ncbot.pipelines.cli.robot import game_and_agent

    standard = agent_checkpoint(tmp_path / "run" / "checkpoint.pt")
    game, path, agent = game_and_agent(standard.parent, None)  # a run folder: its checkpoint.pt, its game
    assert (game, path, agent[0].env.game) == ("standard", standard, "standard")
    assert game_and_agent(None, None)[0] == "standard" and game_and_agent(None, "ultimate")[0] == "ultimate"
    with pytest.raises(ValueError, match="--game ultimate does not match the checkpoint, which plays standard"):
        game_and_agent(standard, "ultimate")
    for command in (["robot", "play"], ["robot", "serve"]):
        one_line_error(ncbot(*command, str(standard), "--game", "ultimate"), "which plays standard; drop --game")


def test_a_declared_checkpoint_plays_its_own_game_on_the_robot(tmp_path: Path) -> None:
    from ncbot.pipelines.cli.robot import game_and_agent

    four = agent_checkpoint(tmp_path / "four" / "checkpoint.pt", game="four")
    assert game_and_agent(four.parent, None)[0] == "four" and game_and_agent(four, "four")[0] == "four"
    assert game_and_agent(None, "connect_four")[0] == "connect_four"
    for command in (["robot", "play"], ["robot", "serve"]):
        one_line_error(ncbot(*command, str(four), "--game", "connect_four"),
                       "--game connect_four does not match the checkpoint, which plays four; drop --game")
        one_line_error(ncbot(*command, "--game", "nosuchgame"), "game must be one of standard, ultimate")


# ------------------------------------------------------------------------------------------------ cells
def test_cells_a_person_reads_are_written_b2() -> None:
    from ncbot.logs.names import NameTables

    standard = NameTables(action_names=[f"GameMove(gridloc={c})" for c in range(9)] + ["Provide(feedback)"])
    assert standard.action_name(4) == "GameMove(b2)" and standard.action_name(9) == "Provide(feedback)"
    assert standard.readable("GameMove(gridloc=8)") == "GameMove(c3)" and standard.cell_name(0) == "a1"
    ultimate = NameTables(action_names=[f"GameMove(gridloc={c})" for c in range(81)])
    assert ultimate.action_name(40) == "GameMove(e5)" and ultimate.cell_name(80) == "i9"


# ------------------------------------------------------------------------------------------------ rough edges
def test_out_on_a_virtual_file_system_is_not_writable_not_full(tmp_path: Path) -> None:
    checkpoint = agent_checkpoint(tmp_path / "checkpoint.pt")
    err = one_line_error(ncbot("eval", str(checkpoint), "--games", "1", "--out", "/proc/ncbot-test"),
                         "--out '/proc/ncbot-test' is not writable")
    assert "space" not in err and "full" not in err


def test_robot_play_games_out_of_range_is_our_line() -> None:
    err = one_line_error(ncbot("robot", "play", "--games", "-1"), "--games must be a number of games from 1 to 10000")
    assert "pydantic" not in err and "greater than" not in err


def test_train_of_an_ablation_grid_points_to_ablate() -> None:
    grid = ROOT / "pipelines" / "configs" / "ablation.yaml"
    one_line_error(ncbot("train", str(grid)), "is an ablation grid, not a run config: run ncbot ablate")


def write_grid(tmp_path: Path) -> Path:
    from tests.learning_helpers import write_tiny_config

    write_tiny_config(tmp_path)
    grid = tmp_path / "grid.yaml"
    grid.write_text(yaml.safe_dump({
        "runs_dir": str(tmp_path / "runs"),
        "suites": {"s": {"standard": {"config": "tiny.yaml", "overrides": []}}},
        "grid": {"suite": ["s"], "game": ["standard"], "agent": ["proposed", "dqn_original"], "temporal": [False]}}))
    return grid


def test_ablate_only_that_matches_nothing_is_an_error(tmp_path: Path) -> None:
    grid = write_grid(tmp_path)
    one_line_error(ncbot("ablate", str(grid), "--seeds", "1", "--only", "nomatch"),
                   "--only 'nomatch' matches none of the 2 runs", "s/standard/proposed-notemporal/seed0")
    assert not (tmp_path / "runs").exists()


def test_ablate_overrides_apply_to_every_run(tmp_path: Path) -> None:
    from ncbot.pipelines.grid.plan import plan_runs

    grid = write_grid(tmp_path)
    runs = plan_runs(grid, seeds=2, overrides=["optim.lr=0.002"])
    assert len(runs) == 4 and all("optim.lr=0.002" in run.overrides for run in runs)
    with pytest.raises(ValueError, match="sets agent.name, which each grid cell sets itself"):
        plan_runs(grid, seeds=1, overrides=["agent.name=dqn_variant"])
    one_line_error(ncbot("ablate", str(grid), "optim.lr=fast", "--seeds", "1"), "optim.lr")
    one_line_error(ncbot("ablate", str(grid), "optim.lr", "--seeds", "1"), "is not key=value")


def test_ctrl_c_advises_what_fits_the_command(tmp_path: Path, monkeypatch, capsys) -> None:
    import ncbot.pipelines.evaluate.games as evaluate_games
    import ncbot.pipelines.grid.runner as runner
    from ncbot.pipelines.cli.app import main, resume_advice

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(runner, "run_ablation", interrupted)
    monkeypatch.setattr(evaluate_games, "evaluate_checkpoint", interrupted)
    checkpoint = agent_checkpoint(tmp_path / "checkpoint.pt")
    for args, expected in ((["eval", str(checkpoint), "--games", "1"], "ncbot: interrupted (Ctrl-C)"),
                           (["ablate", str(write_grid(tmp_path))],
                            "ncbot: interrupted (Ctrl-C); run the same ncbot ablate command again to go on: it skips "
                            "the finished runs")):
        with pytest.raises(SystemExit) as done:
            main(args)
        assert done.value.code == 130
        assert capsys.readouterr().err.strip() == expected
    assert resume_advice(["train", "x.yaml"]) == "" and resume_advice(["play"]) == ""  # train names its folder itself


def test_table_labels_rows_by_the_runs_hidden_widths(tmp_path: Path) -> None:
    from ncbot.pipelines.reproduce.table import write_report

    for seed in range(2):
        folder = tmp_path / "fast" / "standard" / "proposed-temporal" / f"seed{seed}"
        folder.mkdir(parents=True)
        (folder / "eval.json").write_text(json.dumps({
            "frames": 1000, "train_wall_time_s": 10.0, "run_id": f"r{seed}",
            "first": {"games": 100, "avg_reward": 0.5, "task_success": 0.9 + seed / 100, "avg_length": 10.0},
            "second": {"games": 100, "task_success": 0.8}, "history": []}))
        (folder / "config.yaml").write_text(yaml.safe_dump({"env": {"game": "standard"},
                                                            "agent": {"hidden": [256, 256]}}))
    report = write_report(tmp_path, None, None, command="ncbot table")
    assert "| 3x3 (256, 256) |" in report.table and "3x3 (100)" not in report.table
    assert report.to_dict()["rows"][0]["game_label"] == "3x3 (256, 256)"
