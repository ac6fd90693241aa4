"""`ncbot eval`: JSON with exactly the documented keys, seats, and one-line errors for bad input."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

from ncbot.pipelines.config import load_config
from ncbot.modules.policies.mask_rules import all_moves_negative
from ncbot.pipelines.evaluate.games import GameRecords, evaluate_checkpoint, summarise, wilson_interval
from ncbot.pipelines.train.run import train
from tests.learning_helpers import ncbot, write_tiny_config

torch.set_num_threads(1)
KEYS = {"games", "win", "draw", "loss", "truncated", "all_negative", "task_success", "task_success_ci95", "avg_reward",
        "avg_return", "avg_length"}


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("eval")
    train(load_config(write_tiny_config(folder), ["collector.total_frames=256"]), folder / "run")
    return folder / "run" / "checkpoint.pt"


def test_eval_json_has_exactly_the_documented_keys(checkpoint: Path) -> None:
    result = ncbot("eval", str(checkpoint), "--games", "40", "--first", "human", "--seed", "1", "--json")
    assert result.returncode == 0, result.stderr
    data = json.loads(result.stdout)
    assert set(data) == KEYS | {"opens", "second"}  # the games of each seat played, keyed as eval.json keys them
    assert data["opens"] == "human" and {key: data["second"][key] for key in KEYS} == {key: data[key] for key in KEYS}
    assert data["games"] == 40
    assert abs(data["win"] + data["draw"] + data["loss"] + data["truncated"] - 1) < 1e-9
    assert data["task_success"] == pytest.approx(data["win"] + data["draw"])
    low, high = data["task_success_ci95"]
    assert 0 <= low <= data["task_success"] <= high <= 1
    assert data["avg_length"] > 5  # greeting, name, play request, moves, feedback, closing


def test_seats_are_respected_and_seeded(checkpoint: Path) -> None:
    first = evaluate_checkpoint(checkpoint, games=50, first="robot", seed=0)
    again = evaluate_checkpoint(checkpoint, games=50, first="robot", seed=0)
    assert first == again
    second = evaluate_checkpoint(checkpoint, games=50, first="human", seed=0)
    assert second != first  # robot-second games are other games (the user moves first)
    both = evaluate_checkpoint(checkpoint, games=51, first="alternate", seed=0)
    assert both.games == 51


def test_metrics_from_known_games() -> None:
    outcomes = torch.tensor([1, 1, 3, 2, 0])  # win, win, draw, loss, unfinished at the act cap
    returns = torch.tensor([10.0, 5.0, 1.0, -5.0, -20.0])
    lengths = torch.tensor([10, 10, 12, 8, 100])
    truncated = torch.tensor([False, False, False, False, True])
    negative = torch.tensor([False, True, False, True, True])
    result = summarise(GameRecords(outcomes, returns, lengths, truncated, negative))
    assert (result.win, result.draw, result.loss, result.truncated, result.task_success) == (0.4, 0.2, 0.2, 0.2, 0.6)
    assert result.all_negative == pytest.approx(0.6)
    assert result.avg_reward == pytest.approx(-9.0 / 140)  # per action, as the paper
    assert result.avg_return == pytest.approx(-1.8) and result.avg_length == pytest.approx(28.0)
    assert wilson_interval(3000, 3000)[0] == pytest.approx(0.99872, abs=1e-4)


def test_bad_input_is_one_line_and_exit_2(tmp_path: Path, checkpoint: Path) -> None:
    missing = ncbot("eval", str(tmp_path / "nope.pt"), "--games", "5")
    assert missing.returncode == 2 and len(missing.stderr.strip().splitlines()) == 1 and "not found" in missing.stderr
    corrupt = tmp_path / "corrupt.pt"
    corrupt.write_bytes(checkpoint.read_bytes()[:200])
    result = ncbot("eval", str(corrupt), "--games", "5")
    assert result.returncode == 2 and len(result.stderr.strip().splitlines()) == 1 and "corrupt" in result.stderr
    with pytest.raises(ValueError, match="first must be one of robot, human, alternate, got 'third'"):
        evaluate_checkpoint(checkpoint, games=5, first="third")
    with pytest.raises(ValueError, match="games must be a positive number"):
        evaluate_checkpoint(checkpoint, games=0)


def test_first_is_the_one_name_of_who_opens(checkpoint: Path) -> None:
    """`--first robot|human|alternate` only: the old `--seat` is an unknown option, a bad value one line."""
    old = ncbot("eval", str(checkpoint), "--games", "30", "--seat", "second")
    assert old.returncode == 2 and "No such option: --seat" in old.stderr
    bad = ncbot("eval", str(checkpoint), "--first", "pepper")
    assert bad.returncode == 2 and "--first must be one of robot, human, alternate" in bad.stderr


def test_games_cut_at_the_act_cap_are_truncated_not_lost(checkpoint: Path) -> None:
    from ncbot.pipelines.agents import load_agent
    from ncbot.pipelines.evaluate.games import evaluate_agent

    config, policy = load_agent(checkpoint)
    config.env.max_steps = 5  # greeting, name, play request and two moves: no game can end
    result = evaluate_agent(config, policy, games=20, first="alternate", seed=0)
    assert (result.truncated, result.loss, result.task_success) == (1.0, 0.0, 0.0)
    assert set(result.seats) == {"robot_first", "robot_second"}
    assert [result.seats[s]["games"] for s in ("robot_first", "robot_second")] == [10, 10]
    assert all(result.seats[s]["truncated"] == 1.0 for s in result.seats)


def test_all_moves_negative_needs_an_offered_move_and_no_other() -> None:
    mask = torch.tensor([[True, True, False, True], [True, False, False, True], [False, False, False, True]])
    reward = torch.tensor([[-5.0, 0.0, 5.0, 0.0], [-5.0, 5.0, 0.0, 0.0], [-5.0, -5.0, -5.0, 0.0]])
    # 3 cells + 1 dialogue act: row 0 has a quiet move, row 1 only a -5 move, row 2 no move offered
    assert all_moves_negative(mask, reward, cells=3).tolist() == [False, True, False]


def test_the_log_holds_exactly_the_counted_games(checkpoint: Path, tmp_path: Path) -> None:
    """Slots that finish early start other games while the slowest counted game runs; those are not logged, so the
    log's outcomes are the report's (a log with extra games would favour the short ones)."""
    from ncbot.logs import EpisodeLogger
    from ncbot.logs.reader import read_episodes
    from ncbot.pipelines.agents import load_agent
    from ncbot.pipelines.evaluate.games import evaluate_agent

    config, policy = load_agent(checkpoint)
    config.env.taken_squares = "refused"  # some games repeat a taken square up to the act cap, others end in ~10 acts
    with EpisodeLogger(tmp_path / "log") as logger:
        result = evaluate_agent(config, policy, games=60, first="robot", seed=2, logger=logger)
    logged = [e for e in read_episodes(tmp_path / "log") if e["phase"] == "eval"]
    assert max(e["length"] for e in logged) >= 4 * min(e["length"] for e in logged)  # slots do finish early
    assert len(logged) == result.games == 60
    assert sum(e["outcome"] == "win" for e in logged) / 60 == pytest.approx(result.win)
    assert sum(e["length"] for e in logged) / 60 == pytest.approx(result.avg_length)


def test_progress_goes_to_stderr_as_lines_in_a_pipe_and_off_with_no_progress(checkpoint: Path) -> None:
    """A long evaluation shows games done, rate and ETA; in a pipe as plain lines on stderr (stdout keeps the
    results, or the JSON, alone), and nothing with --no-progress. Same results either way."""
    shown = ncbot("eval", str(checkpoint), "--games", "60", "--seed", "2", "--json")
    assert shown.returncode == 0, shown.stderr
    lines = [line for line in shown.stderr.splitlines() if line.startswith("eval")]
    assert len(lines) >= 2 and "60/60" in lines[-1] and "game" in lines[-1], shown.stderr
    assert "\r" not in shown.stderr
    quiet = ncbot("eval", str(checkpoint), "--games", "60", "--seed", "2", "--json", "--no-progress")
    assert quiet.returncode == 0 and not any(line.startswith("eval") for line in quiet.stderr.splitlines()), quiet.stderr
    assert json.loads(quiet.stdout) == json.loads(shown.stdout)
