"""The paper's readings as options: offered taken squares, paper-shaped dialogues, a games cap.

Real env and a real tiny training run; the option-off env must stay bit-identical to docs/env.md's fingerprints.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
import torch
import yaml

import ncbot.envs.dialogue as dlg
from ncbot.envs import make_env
from ncbot.envs.fingerprint import CONFIGS, fingerprint
from ncbot.pipelines.config import load_config
from ncbot.pipelines.train.run import train
from tests.learning_helpers import write_tiny_config
from tests.envs.helpers import to_robot_move

torch.set_num_threads(1)
ROOT = Path(__file__).resolve().parents[2]


def _recorded_hashes() -> dict[str, str]:
    text = (ROOT / "docs" / "env.md").read_text()
    return dict(re.findall(r"^(\S+/\S+)\s+([0-9a-f]{16})$", text, flags=re.M))


@pytest.mark.parametrize("name", ["standard/robot", "ultimate/robot/dialogue-mask"])
def test_options_off_keep_the_recorded_env_fingerprint(name: str) -> None:
    kwargs, policy = next((k, p) for n, k, p in CONFIGS if n == name)
    expected = _recorded_hashes()[name]
    assert fingerprint(kwargs, policy, 2000, 64) == expected
    explicit = dict(kwargs, taken_squares="never", win_set="wins_and_threats", about_to="standing", dialogues="compact")
    assert fingerprint(explicit, policy, 300, 64) == fingerprint(kwargs, policy, 300, 64)


@pytest.mark.parametrize("game", ["standard", "ultimate"])
def test_a_taken_cell_is_offered_and_refused_with_minus_five(game: str) -> None:
    env = make_env(game, batch_size=(1,), seed=4, first="robot", taken_squares="refused", dialogues="paper")
    td = to_robot_move(env, env.reset())
    first_cell = int(td["action_mask"][0, : env.cells].nonzero()[0])
    td["action"] = torch.tensor([first_cell])
    td = to_robot_move(env, env.step(td)["next"])  # "your turn", the user moves, the robot's turn again
    assert int(td["board"][0, first_cell]) == 1
    assert bool(td["action_mask"][0, first_cell]) and float(td["lookahead_reward"][0, first_cell]) == -5.0
    assert not bool(td["winning_actions"][0, first_cell])
    board, turn = td["board"].clone(), int(td["turn"][0])
    td["action"] = torch.tensor([first_cell])
    after = env.step(td)["next"]
    assert float(after["reward"][0]) == -5.0
    assert torch.equal(after["board"], board)  # the board did not change
    assert int(after["user_move"][0]) == -1 and int(after["user_act"][0]) == -1  # the user did not move or speak
    assert int(after["turn"][0]) == turn + 1
    assert torch.equal(after["action_mask"], td["action_mask"])  # the robot chooses again, from the same offer


def test_taken_cells_are_offered_only_with_the_option_and_only_on_the_robots_turn() -> None:
    for offer in (False, True):
        env = make_env("standard", batch_size=(64,), seed=1, first="alternate", taken_squares="refused" if offer else "never")
        td = env.reset()
        offered_taken = 0
        for _ in range(200):
            taken = td["board"] != 0
            moves = td["action_mask"][:, :9]
            offered_taken += int((moves & taken).sum())
            # a move (legal or taken) is offered only where the act filter allows moves: the robot's turn
            assert not bool((moves & ~td["dialogue_mask"][:, :9]).any())
            td = env.rand_action(td)
            _, td = env.step_and_maybe_reset(td)
        assert (offered_taken > 0) == offer


@pytest.mark.parametrize("game", ["standard", "ultimate"])
def test_paper_dialogues_say_your_turn_before_each_user_move(game: str) -> None:
    dialogues = [d for d in yaml.safe_load(dlg.PAPER_DATA_FILE.read_text())["dialogues"] if d["game"] == game]
    assert len(dialogues) == 12
    moves = 0
    for dialogue in dialogues:
        robot_acts = [turn["robot"] for turn in dialogue["turns"]]
        for turn in dialogue["turns"]:
            if str(turn["user"]).startswith("GameMove"):
                moves += 1
                assert turn["robot"] == "Request(userGameMove)"
        if dialogue["robot_first"]:  # "Nice. Let me start." right before the robot's first move
            first_move = next(i for i, act in enumerate(robot_acts) if act.startswith("GameMove"))
            assert robot_acts[first_move - 1] == "Reply(playGame=yes)"
    assert moves > 24
    model = dlg.build_dialogue_model(game, "paper")
    assert len(model.words) == 39  # the paper's vocabulary size: 73 / 289 features with the temporal ones
    assert model.templates[dlg.REPLY_YES] == "Nice. Let me start."


def test_paper_env_user_moves_only_after_your_turn() -> None:
    env = make_env("standard", batch_size=(128,), seed=2, first="alternate", dialogues="paper")
    assert env.n_features == 73 and env.templates[env.cells + dlg.REPLY_YES - 1] == "Nice. Let me start."
    your_turn = env.cells + dlg.REQUEST_USER_MOVE - 1
    td = env.reset()
    user_moves = 0
    lengths = []
    for _ in range(400):
        td = env.rand_action(td)
        stepped, td = env.step_and_maybe_reset(td)
        moved = stepped["next", "user_move"][:, 0] >= 0
        user_moves += int(moved.sum())
        assert bool((stepped["action"][moved] == your_turn).all())
        done = stepped["next", "done"][:, 0]
        lengths += stepped["next", "turn"][done, 0].tolist()
    assert user_moves > 500 and lengths
    compact = make_env("standard", batch_size=(1,), dialogues="compact")
    assert compact.templates[compact.cells + dlg.REPLY_YES - 1] == dlg.TEMPLATES[dlg.REPLY_YES]


def test_bad_option_values_are_one_clear_error() -> None:
    with pytest.raises(ValueError, match="dialogues must be one of compact, paper"):
        make_env("standard", dialogues="long")
    with pytest.raises(ValueError, match="taken_squares must be one of never, refused, misread"):
        make_env("standard", taken_squares="yes")
    with pytest.raises(ValueError, match="unknown option 'offer_taken_cells'"):
        make_env("standard", offer_taken_cells=True)
    with pytest.raises(ValueError, match="offer_taken_cells"):
        load_config(ROOT / "pipelines" / "configs" / "default.yaml", ["env.offer_taken_cells=true"])
    with pytest.raises(ValueError, match="env.dialogues"):
        load_config(ROOT / "pipelines" / "configs" / "default.yaml", ["env.dialogues=long"])


def test_paper_configs_turn_every_option_on_and_fast_configs_leave_them_off() -> None:
    for path in sorted((ROOT / "pipelines" / "configs" / "paper").glob("*.yaml")):
        config = load_config(path)
        assert config.env.taken_squares == "misread" and config.env.misread_rate == 0.10, path
        assert config.env.win_set == "wins" and config.env.about_to == "standing", path
        assert config.agent.all_negative == "untaken", path
        assert config.env.dialogues == "paper" and config.train.max_games == 20000, path
    for name in ("default", "ultimate", "selfplay"):
        config = load_config(ROOT / "pipelines" / "configs" / f"{name}.yaml")
        assert config.env.taken_squares == "never" and config.env.misread_rate is None, name
        assert config.env.win_set == "wins_and_threats" and config.env.about_to == "standing", name
        assert config.agent.all_negative == "available", name
        assert config.env.dialogues == "compact" and config.train.max_games is None


def test_max_games_stops_training_before_the_frames(tmp_path: Path) -> None:
    config = load_config(write_tiny_config(tmp_path), ["train.max_games=20", "collector.total_frames=5000",
                                                       "env.taken_squares=refused", "env.dialogues=paper"])
    report = train(config, tmp_path / "run")
    assert 20 <= report["episodes"] < 20 + 64  # stopped within the collector batch that passed 20 games
    assert report["frames"] < 5000
    saved = json.loads((tmp_path / "run" / "eval.json").read_text())
    assert saved["episodes"] == report["episodes"] and saved["history"][-1]["frames"] == report["frames"]


def test_an_option_set_twice_is_one_clear_error() -> None:
    from ncbot.pipelines.run_env import make_run_env

    config = load_config(ROOT / "pipelines" / "configs" / "default.yaml", ["env.options={dialogues: paper}"])
    with pytest.raises(ValueError, match="env.options.dialogues repeats the config key env.dialogues"):
        make_run_env(config.env, batch_size=1, seed=0)
