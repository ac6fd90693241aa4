"""Robot games that learn: a `RobotGameRunner`'s games feed one person's learning as they are played.

During a game the runner hands every look after a settled move to `GameViews` (the reader's examples); after it,
the game is read back from the run's MCAP log (its transitions, for the play) and both learners learn; the runner
then reads with the updated classifier and plays with the updated agent (its network is updated in place).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from ncbot.pipelines.online.learning import PersonLearning
from ncbot.pipelines.online.logged import read_games
from ncbot.robot_sim.settlement import GameViews


def last_game(log_dir: str | Path, seed: int):
    """The newest robot game of game seed `seed` in a log folder (without its camera frames), or None."""
    found = None
    for game in read_games(log_dir, frames=False):
        if int(game.summary.get("seed", -1)) == seed:
            found = game
    return found


class LearningRunner:
    """Connects a runner to a person's learning: `after_game` is the runner's hook (`RobotGameRunner.run`)."""

    def __init__(self, learning: PersonLearning, runner: Any) -> None:
        if runner.logger is None:
            raise ValueError("learning from play reads each game back from the run's MCAP log: give --out DIR")
        self.learning = learning
        self.views = GameViews(runner.grid, runner.config.jpeg_quality)
        runner.on_view = self.views.add
        if learning.reader is not None:
            runner.recogniser.classifier = learning.reader.classifier

    def after_game(self, runner: Any, record: Any) -> None:
        """Learn from the game just played (gradients on, also where the games run under no_grad); the runner
        goes on with what was learned."""
        import torch

        with torch.enable_grad():
            self._learn(runner, record)

    def _learn(self, runner: Any, record: Any) -> None:
        runner.logger.flush()
        game = last_game(runner.logger.run_dir, runner.config.seed * 1000 + record.index)
        played = {"outcome": record.outcome, "human_moves": record.human_moves,
                  "misrecognised_moves": record.misrecognised_moves, "unseen_moves": record.unseen_moves,
                  "handwriting": record.conditions.get("handwriting")}
        record.learned = self.learning.learn(self.views.take(), runner.settle(), record.robot_first, game, played)
        if self.learning.reader is not None:
            runner.recogniser.classifier = self.learning.reader.classifier


def play_and_learn(config: Any, checkpoint: str | Path | None, out: Path, person: str, settings: Any,
                   progress: Any = None) -> dict[str, Any]:
    """`ncbot robot play --learn`: play `config.games` games, learning after each; a folder that already holds this
    person's learning resumes after the games it learned from. Returns the report (with `per_game` over every game
    learned, `learned_weights`, and the before / after figures of `learning`)."""
    from ncbot.modules.policies.masks import LookaheadOnlyPolicy
    from ncbot.pipelines.online.summary import draw_learning, play_before_after, reader_before_after
    from ncbot.robot_sim.play import play_robot_games
    from ncbot.robot_sim.report import write_report

    folder = out / "learning" / person
    learning = PersonLearning.open(folder, settings, weights=config.weights, checkpoint=checkpoint)
    policy = learning.play.policy if learning.play is not None else LookaheadOnlyPolicy(seed=config.seed)
    if checkpoint is not None and learning.play is None:
        from ncbot.pipelines.agents import load_agent

        policy = load_agent(checkpoint)[1]

    def attach(runner: Any) -> tuple[Any, int]:
        return LearningRunner(learning, runner).after_game, learning.games

    report = play_robot_games(config, policy, out_dir=out, progress=progress, attach=attach)
    styles = list(config.condition_ranges().handwriting)
    summary = {"person": person, "folder": str(folder), "games_learned": learning.games,
               "reader": reader_before_after(learning, styles),
               "play": play_before_after(learning, [config.human.opponent]),
               "play_weights": learning.play_weights}
    summary["figure"] = str(draw_learning(learning.per_game, summary["reader"], out / "learning.png",
                                          f"learning from play: {person}, handwriting {', '.join(styles)}"))
    report.update(per_game=learning.per_game, learned_weights=learning.reader_weights, learning=summary)
    write_report(report, out)
    return report
