"""`ncbot reproduce games-data`: the data each game needed, read from run folders (pipelines/reproduce/games_data.py)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from ncbot.pipelines.reproduce.games_data import count_dialogues, read_run, shared_cells, write_games_data
from tests.learning_helpers import ncbot

# (training games, frames, task success): crosses 0.95 at the third evaluation, never 0.99
HISTORY = [(100, 1024, 0.50), (250, 2048, 0.94), (400, 3072, 0.96), (600, 4096, 0.95), (800, 5120, 0.985)]


def _seat(success: float) -> dict:
    return {"games": 300, "task_success": success, "task_success_ci95": [success - 0.01, min(1.0, success + 0.01)]}


def fake_run(folder: Path, game: str = "four", history: list = HISTORY, eval_json: bool = True,
             env: dict | None = None) -> Path:
    folder.mkdir(parents=True)
    (folder / "config.yaml").write_text(yaml.safe_dump({"env": {"game": game, **(env or {})}, "train": {"seed": 3}}))
    (folder / "run.json").write_text(json.dumps({"run_id": "x", "created": 1795858221.0}))
    if eval_json:
        (folder / "eval.json").write_text(json.dumps({
            "history": [{"episodes": g, "frames": f, "task_success": s, "games": 200} for g, f, s in history],
            "first": _seat(0.99), "second": _seat(0.97)}))
    return folder


def test_first_crossings_and_not_reached(tmp_path: Path) -> None:
    run = read_run(fake_run(tmp_path / "four"))
    assert run.first_reaching(0.95) == (400, 3072)  # 0.94 is not 0.95; the first at or above it counts
    assert run.first_reaching(0.99) is None
    assert (run.name, run.rows, run.cols, run.k, run.gravity, run.seed) == ("four", 4, 4, 4, False, 3)
    written = write_games_data([tmp_path / "four"], tmp_path / "out", "ncbot reproduce games-data four")
    text = (tmp_path / "out" / "games_data.md").read_text()
    row = next(line for line in text.splitlines() if line.startswith("| `four`"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[4:7] == ["400 (3,072 frames)", "not reached", "200 games"]
    assert cells[3] == f"{shared_cells():,} shared, 0 new"
    assert cells[7] == "0.9900 [0.9800, 1.0000] (300)" and cells[8] == "0.9700 [0.9600, 0.9800] (300)"
    assert "2026-11-28" in cells[9] and "(seed 3)" in cells[9]
    assert Path(written["files"][1]).stat().st_size > 0


def test_a_run_that_never_reaches_either_threshold(tmp_path: Path) -> None:
    run = read_run(fake_run(tmp_path / "slow", history=[(100, 1024, 0.2), (200, 2048, 0.949)]))
    assert run.first_reaching(0.95) is None and run.first_reaching(0.99) is None


def test_a_folder_without_eval_json_is_a_one_line_error_naming_it(tmp_path: Path) -> None:
    unfinished = fake_run(tmp_path / "unfinished", eval_json=False)
    with pytest.raises(ValueError, match=f"run folder {unfinished} holds no eval.json"):
        write_games_data([fake_run(tmp_path / "done"), unfinished], tmp_path / "out", "cmd")
    assert not (tmp_path / "out").exists()  # every folder is read before anything is written
    result = ncbot("reproduce", "games-data", str(unfinished), "--out", str(tmp_path / "out"))
    assert result.returncode == 2 and len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert str(unfinished) in result.stderr and "eval.json" in result.stderr and "Traceback" not in result.stderr


def test_run_folders_belong_to_games_data_only(tmp_path: Path) -> None:
    result = ncbot("reproduce", "table", str(tmp_path), "--budget", "quick", "--out", str(tmp_path / "out"))
    assert result.returncode == 2 and "only games-data and memory take run folders" in result.stderr, result.stderr


@pytest.mark.parametrize("game, dialogues, subset", [("four", "compact", None), ("standard", "compact", None),
                                                      ("standard", "paper", (4, 1))])
def test_the_dialogue_count_is_what_the_env_learns_from(game: str, dialogues: str, subset: tuple | None) -> None:
    from ncbot.envs import make_env
    from ncbot.envs.dialogue import dialogue_set, load_dialogues

    env = make_env(game=game, dialogues=dialogues, dialogue_subset=subset)
    count, turns = count_dialogues(game, dialogues, subset)
    assert turns == env.model.n_examples  # one act-filter example per robot turn of the dialogues counted
    expected = subset[0] if subset else len(load_dialogues(game, dialogue_set(dialogues).path))
    assert count == expected and count > 0


def test_a_declared_game_counts_its_generated_dialogues(tmp_path: Path) -> None:
    declaration = tmp_path / "tiny.yaml"
    declaration.write_text("name: tiny\nrows: 3\ncols: 4\nk: 3\ngravity: true\n")
    run = read_run(fake_run(tmp_path / "tiny", game=str(declaration)))
    assert (run.name, run.rows, run.cols, run.gravity) == ("tiny", 3, 4, True)
    assert (run.dialogues, run.dialogue_turns) == count_dialogues(str(declaration.resolve()), "compact", None)
