"""A recurrent checkpoint (agent.memory=gru) plays everywhere a checkpoint plays: the ladder with other masks, the
exact evaluation, `ncbot play` at the terminal and the SAPIEN robot game (the browser's runner), each carrying the
hidden state through the dialogue from zero at every game; what reads the network on dialogue-less positions (the
Q-guided search, the agent:/qmcts: opponents) refuses with one line."""
from __future__ import annotations

from pathlib import Path

import pytest
import torch

from ncbot.modules.networks.recurrent import IS_INIT_KEY
from ncbot.pipelines.config import load_config
from ncbot.pipelines.train.run import train
from tests.learning_helpers import write_tiny_config

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def gru_checkpoint(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("gru")
    config = load_config(write_tiny_config(folder, buffer={"sequence_length": 8, "burn_in": 2}),
                         ["agent.memory=gru", "collector.total_frames=256", "eval.games=20"])
    train(config, folder / "run")
    return folder / "run" / "checkpoint.pt"


class StateRecorder:
    """The greedy policy, called through a wrapper as the browser's session calls it (under a lock), keeping
    what it saw of the hidden state at each step."""

    def __init__(self, policy) -> None:
        self.policy, self.steps = policy, []

    def __call__(self, td):
        self.steps.append((bool(td.get(IS_INIT_KEY).all()), td.get("recurrent_state").clone()))
        td = self.policy(td)
        self.steps[-1] += (td.get(("next", "recurrent_state")).clone(),)
        return td


def _check_carried(steps: list) -> None:
    """First step of the game: is_init and the zero state; every later step starts from the state the one before
    it left, and the state is not stuck at zero."""
    assert steps[0][0] and float(steps[0][1].abs().max()) == 0.0
    for (_, _, left), (is_init, state, _) in zip(steps, steps[1:]):
        assert not is_init and torch.equal(state, left)
    assert float(steps[-1][1].abs().max()) > 0.0


def test_ladder_masks_and_exact_evaluation_play_a_recurrent_agent(gru_checkpoint: Path) -> None:
    from ncbot.pipelines.agents import load_robot
    from ncbot.pipelines.evaluate.exact import exact_checkpoint
    from ncbot.pipelines.evaluate.games import evaluate_agent

    config, policy, description = load_robot(str(gru_checkpoint), lookahead="k2")
    assert "masks k2" in description
    result = evaluate_agent(config, policy, games=20, first="alternate", seed=1, opponent="minimax")
    assert result.games == 20 and result.win + result.draw + result.loss + result.truncated == pytest.approx(1.0)
    exact = exact_checkpoint(gru_checkpoint, first="human", dialogue_seeds=1)  # 945 user branches, each a dialogue
    assert exact[0].branches == 945 and exact[0].win + exact[0].draw + exact[0].loss == pytest.approx(1.0)


def test_dialogue_less_readers_refuse_a_recurrent_agent_with_one_line(gru_checkpoint: Path) -> None:
    from ncbot.pipelines.agents import AgentOpponent, load_guided_agent, load_robot

    for call in (lambda: load_robot(str(gru_checkpoint), search=4),
                 lambda: load_guided_agent(str(gru_checkpoint), 4),
                 lambda: AgentOpponent(str(gru_checkpoint), "standard", "anywhere", 0)):
        with pytest.raises(ValueError, match="does not support agent.memory=gru") as error:
            call()
        assert "\n" not in str(error.value)


def test_terminal_play_carries_the_state_through_the_dialogue(gru_checkpoint: Path, tmp_path: Path) -> None:
    """`ncbot play`'s loop with the person's input scripted: moves tried square by square (illegal ones are
    explained and asked again), silence to every other act."""
    from ncbot.pipelines.evaluate.play import Console, play_dialogue

    squares = iter([f"{column}{row}" for _ in range(20) for row in "123" for column in "abc"])
    shown: list[str] = []
    console = Console(read=lambda prompt: next(squares) if prompt.startswith("Your move") else "",
                      write=shown.append)
    summary = play_dialogue(checkpoint=str(gru_checkpoint), first="human", console=console,
                            log_dir=str(tmp_path / "log"))
    assert summary["agent"] == "proposed" and summary["actions"] > 3
    assert any(line.startswith("Pepper:") for line in shown)
    from ncbot.logs import read_episodes

    assert len(read_episodes(tmp_path / "log")) == 1


@pytest.mark.sapien
def test_a_robot_game_carries_the_state_through_its_dialogue(sapien_render_system, gru_checkpoint: Path,
                                                             tmp_path: Path) -> None:
    """The runner `ncbot robot play` and the browser's sessions use, with the policy behind a wrapper as serve
    calls it (`network=` names the module): one short game."""
    from ncbot.pipelines.agents import load_agent
    from ncbot.robot_sim.game_config import RobotPlayConfig
    from ncbot.robot_sim.play import RobotGameRunner

    _, greedy = load_agent(gru_checkpoint)
    recorder = StateRecorder(greedy)
    config = RobotPlayConfig(game="standard", games=1, seed=5, camera_width=160, camera_height=120,
                             robot_frame_period=1.0, first="robot")
    with torch.no_grad():
        report = RobotGameRunner(config, recorder, out_dir=tmp_path, network=greedy).run()
    assert report["games"] == 1 and len(recorder.steps) >= 3
    _check_carried(recorder.steps)
