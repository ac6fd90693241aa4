"""`ncbot logs acts` on the logs of real tiny training runs: rows that add up to the dialogue length, refused moves
found where the `refused` reading lets an untrained agent repeat taken squares, none where squares are never
offered."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from ncbot.logs.acts import GAME_MOVES, REFUSED
from ncbot.logs.reader import read_episode_records
from tests.learning_helpers import ncbot, write_tiny_config
from tests.logs.helpers import run_cli


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Untrained DQN-Original (no masks) under the paper's dialogues with taken squares offered and refused, and
    under the compact dialogues with taken squares never offered; their test games logged to MCAP."""
    folder = tmp_path_factory.mktemp("acts")
    config = write_tiny_config(folder, env={"first": "robot"}, eval={"games": 20, "periodic_games": 10},
                               logger={"mcap": True, "progress": False})
    made = {}
    for name, overrides in (("refused", ["env.taken_squares=refused", "env.dialogues=paper"]),
                            ("never", ["env.taken_squares=never", "env.dialogues=compact"])):
        done = ncbot("train", str(config), "agent.name=dqn_original", *overrides, "--out", str(folder / name))
        assert done.returncode == 0, done.stderr
        made[name] = folder / name
    return made


def _table(run: Path, capsys: pytest.CaptureFixture, *options: str) -> dict:
    code, out, err = run_cli("logs", "acts", run, "--json", *options, capsys=capsys)
    assert code == 0, err
    return json.loads(out)


def _final_robot_marks(run: Path) -> float:
    """Mean robot marks on each test game's last logged board: read off the boards, not counted from the acts."""
    records = [r for r in read_episode_records(run).values() if r.summary and r.summary["phase"] == "eval"]
    return sum(r.boards[-1]["cells"].count("1") for r in records) / len(records)


@pytest.mark.parametrize("reading", ["refused", "never"])
def test_rows_add_up_to_the_length_and_accepted_moves_to_the_marks(runs: dict[str, Path], reading: str,
                                                                  capsys: pytest.CaptureFixture) -> None:
    table = _table(runs[reading], capsys)
    assert table["phase"] == "eval" and list(table["groups"])[0] == "all"
    every = table["groups"]["all"]
    assert every["games"] == sum(group["games"] for label, group in table["groups"].items() if label != "all")
    for group in table["groups"].values():
        spoken = sum(count for name, count in group["acts"].items() if name != REFUSED)
        assert spoken == pytest.approx(group["mean_length"])
    accepted = every["acts"][GAME_MOVES] - every["acts"][REFUSED]
    assert accepted == pytest.approx(_final_robot_marks(runs[reading]))


def test_refused_moves_are_found_only_where_taken_squares_are_offered(runs: dict[str, Path],
                                                                     capsys: pytest.CaptureFixture) -> None:
    looping = _table(runs["refused"], capsys)["groups"]["all"]["acts"]
    assert looping[REFUSED] > 0.5 * looping[GAME_MOVES]  # no masks, nothing changes after a refusal: it repeats
    assert looping["Request(userGameMove)"] > 0  # the paper's dialogues say "your turn"
    assert _table(runs["never"], capsys)["groups"]["all"]["acts"][REFUSED] == 0.0


def test_seat_filter_text_table_and_bad_options(runs: dict[str, Path], capsys: pytest.CaptureFixture) -> None:
    first = _table(runs["never"], capsys, "--seat", "first")
    assert first["seat"] == "first" and first["groups"]["all"]["games"] > 0
    with_second = _table(runs["never"], capsys, "--seat", "second")["groups"]["all"]["games"]
    assert first["groups"]["all"]["games"] + with_second == _table(runs["never"], capsys)["groups"]["all"]["games"]
    code, out, _ = run_cli("logs", "acts", runs["never"], capsys=capsys)
    assert code == 0 and "| dialogue length |" in out and "of which refused" in out
    for options, message in ((["--seat", "left"], "--seat must be first or second"),
                             (["--phase", "robot"], "no finished episode with logged steps for phase robot")):
        code, _, err = run_cli("logs", "acts", runs["never"], *options, capsys=capsys)
        assert code == 2 and message in err
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
