"""A robot game the env never ended (the robot's belief and the true board parted) still gets its `/episode`
summary, under the id its per-action steps were written with, so a log keeps every game (`ncbot learn` reads it)."""
from __future__ import annotations

from torchrl.envs.utils import step_mdp

from ncbot.envs import make_env
from ncbot.logs import EpisodeLogger
from ncbot.logs.reader import read_episode_records


def test_a_cut_off_game_is_summarised_under_its_steps_id_and_the_next_game_goes_on(tmp_path) -> None:
    env = make_env("standard", batch_size=(1,), seed=3)
    with EpisodeLogger(tmp_path) as log:
        assert log.cut_off("robot", "test", 3) is None, "nothing running: nothing to end"
        td = env.reset()
        for _ in range(3):  # three acts of a game, then the robot stops it
            td["action"] = td["action_mask"].float().argmax(-1)
            td = env.step(td)
            log.record_steps(td, phase="robot", agent="test", seed=3, env=env)
            td = step_mdp(td)
        cut = log.cut_off("robot", "test", 3, extra={"true_outcome": "unfinished"})
        td = env.reset()
        while True:  # the next game, played to its end
            td["action"] = td["action_mask"].float().argmax(-1)
            td = env.step(td)
            log.record_steps(td, phase="robot", agent="test", seed=3, env=env)
            if bool(td["next", "done"].item()):
                break
            td = step_mdp(td)
    records = read_episode_records(tmp_path)
    assert sorted(records) == [cut, cut + 1]
    first = records[cut]
    assert len(first.steps) == 3 and first.summary["outcome"] == "none" and first.summary["length"] == 3
    assert first.summary["extra"] == {"true_outcome": "unfinished"} and not first.summary["task_success"]
    assert records[cut + 1].summary["outcome"] in ("win", "draw", "loss") and records[cut + 1].steps[0]["step"] == 0
