"""What a user reads is right: Gymnasium after `import ncbot`, one line and nothing before it for a bad argument,
checkpoint messages that say what the file is, act and phase names as shown, and a resumed run that is finished."""
from __future__ import annotations

import json
import os
import random
import subprocess
import sys
from pathlib import Path

import pytest

from tests.cli.conftest import run_main

ROOT = Path(__file__).resolve().parents[2]


def python(code: str, cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True, text=True, timeout=120)


def one_line(code: int, err: str, *needles: str) -> str:
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("ncbot: error: "), err
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


# ------------------------------------------------------------------------------------------------ 1. Gymnasium
@pytest.mark.parametrize("imports", ["import ncbot, gymnasium", "import gymnasium, ncbot"])
def test_gymnasium_makes_the_env_after_import_ncbot(imports: str, tmp_path: Path) -> None:
    done = python(f"{imports}\nenv = gymnasium.make('ncbot/NoughtsCrosses-v0', game='ultimate')\n"
                  "print(env.observation_space.shape, env.action_space.n)", tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["(289,)", "90"]


def test_import_ncbot_stays_light(tmp_path: Path) -> None:
    """The registration waits for gymnasium's own import: `import ncbot` (every ncbot command) loads neither."""
    done = python("import sys, ncbot\nprint('gymnasium' in sys.modules, 'torch' in sys.modules)", tmp_path)
    assert done.returncode == 0 and done.stdout.split() == ["False", "False"], done.stderr


# ------------------------------------------------------------------------------------------------ 2. SAPIEN's warnings
def test_sapiens_import_warnings_stay_off_stderr(tmp_path: Path) -> None:
    """SAPIEN warns when imported on a machine without a system Vulkan library; the CLI shows only its own line."""
    done = python("import warnings\nfrom ncbot.pipelines.cli.app import quiet_library_warnings\n"
                  "quiet_library_warnings()\n"
                  "warnings.warn_explicit('Failed to find system libvulkan.', UserWarning, 'x.py', 1, "
                  "module='sapien._vulkan_tricks')\n"
                  "warnings.warn_explicit('ours', UserWarning, 'x.py', 1, module='ncbot.envs')\n", tmp_path)
    assert "libvulkan" not in done.stderr and "ours" in done.stderr


# ------------------------------------------------------------------------------------------------ 3. bad arguments
@pytest.mark.parametrize("args, needles", [
    (["--games", "-5"], ["--games"]), (["--games", "0"], ["--games"]),
    (["--opponent", "minmax"], ["unknown opponent 'minmax'", "choose one of random"]),
])
def test_a_bad_eval_argument_is_its_line_and_nothing_before_it(tiny_run: Path, capfd, args, needles) -> None:
    code, out, err = run_main(capfd, "eval", tiny_run / "checkpoint.pt", *args)
    line = one_line(code, err, *needles)
    assert out == "" and line.count("minimax") <= 1  # the choices are listed once


def test_an_unknown_opponent_in_a_config_lists_the_choices_once() -> None:
    from ncbot.envs.env_options import resolve_opponent

    with pytest.raises(ValueError) as error:
        resolve_opponent("minmax", "standard", "anywhere", 0)
    assert str(error.value).count("minimax") == 1 and str(error.value).count("choose one of") == 1


# ------------------------------------------------------------------------------------------------ 4. reproduce parts
def test_reproduce_names_every_part_for_a_misspelt_one(capfd) -> None:
    for extra in ([], ["--budget", "quick"]):
        code, _, err = run_main(capfd, "reproduce", "tabel", *extra)
        one_line(code, err, "part must be one of table, vision, budget, all, games-data, memory; got 'tabel'")


# ------------------------------------------------------------------------------------------------ 5, 6. vision read
@pytest.fixture(scope="module")
def photos(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from ncbot.pipelines.cli.app import main

    folder = tmp_path_factory.mktemp("photos")
    for grid, seed in (("3", 3), ("9", 5)):
        with pytest.raises(SystemExit):
            main(["vision", "generate", "frames", "--out", str(folder / f"grid{grid}"), "--n", "1", "--seed", str(seed),
                  "--grid", grid])
    return folder


def test_vision_read_reads_the_images_of_a_folder(photos: Path, capfd) -> None:
    code, out, err = run_main(capfd, "vision", "read", photos / "grid3")
    assert code == 0, err
    assert out.startswith(f"{photos / 'grid3' / 'frame_3x3_3.png'}: X . . / X X X / . . X"), out


@pytest.mark.parametrize("grid, asked, fits", [("3", "9", "it fits --grid 3"), ("9", "3", "it fits --grid 9")])
def test_a_sheet_of_another_grid_is_one_line_naming_what_was_found(photos: Path, capfd, grid, asked, fits) -> None:
    image = next((photos / f"grid{grid}").glob("*.png"))
    code, out, err = run_main(capfd, "vision", "read", image, "--grid", asked)
    assert out == ""
    one_line(code, err, str(image), "lines across", f"not a {asked}x{asked} grid (--grid {asked})", fits)


# ------------------------------------------------------------------------------------------------ 7. checkpoints
@pytest.mark.parametrize("content, said", [
    (b"\x00\x01" + random.Random(0).randbytes(2000), "neither a zip archive nor a pickle"),
    (b"hello world\nthis is not a checkpoint\n", "is not a torch file: it is a text file"),
    (b"", "is not a torch file: it is empty"),
], ids=["random-bytes", "text", "empty"])
def test_a_file_that_is_no_torch_file_is_called_what_it_is(tmp_path: Path, content: bytes, said: str) -> None:
    from ncbot.pipelines.checkpoint import load_checkpoint

    path = tmp_path / "foreign.pt"
    path.write_bytes(content)
    with pytest.raises(ValueError, match=said) as error:
        load_checkpoint(path)
    assert "beyond tensors" not in str(error.value)


def test_a_pickled_object_and_a_cut_checkpoint_keep_their_own_messages(tiny_run: Path, tmp_path: Path) -> None:
    import pickle

    from ncbot.pipelines.checkpoint import load_checkpoint

    objects, cut = tmp_path / "objects.pt", tmp_path / "cut.pt"
    objects.write_bytes(pickle.dumps({"a": object}, protocol=2))
    cut.write_bytes((tiny_run / "checkpoint.pt").read_bytes()[:1000])
    with pytest.raises(ValueError, match="holds Python objects beyond tensors"):
        load_checkpoint(objects)
    with pytest.raises(ValueError, match="is damaged .truncated or not a torch zip file"):
        load_checkpoint(cut)


# ------------------------------------------------------------------------------------------------ 8, 9. names
def test_the_lost_game_act_reads_lose_while_the_data_keeps_the_papers_spelling(capfd) -> None:
    from ncbot.envs import make_env
    from ncbot.logs.names import NameTables

    env = make_env("standard")
    assert "Provide(feedback=loose)" in env.action_names  # the paper's act name (Cuayahuitl 2019)
    shown = NameTables.from_env(env)
    assert "Provide(feedback=lose)" in [shown.action_name(a) for a in range(env.n_actions)]
    code, out, _ = run_main(capfd, "env", "describe")
    assert code == 0 and "Provide(feedback=lose)" in out and "loose" not in out


def test_log_help_lists_the_phases_the_log_records(capfd) -> None:
    from ncbot.logs.schemas import PHASES

    for command in ("episodes", "acts"):
        code, out, _ = run_main(capfd, "logs", command, "--help")
        text = " ".join(out.split())
        assert code == 0 and all(phase in text for phase in PHASES), (command, text)


# ------------------------------------------------------------------------------------------------ 10. training runs
def test_resuming_a_finished_run_says_so_and_rewrites_nothing(tiny_run: Path, capfd) -> None:
    before = {path.name: path.stat().st_mtime_ns for path in tiny_run.iterdir() if path.is_file()}
    code, out, err = run_main(capfd, "train", "--resume", tiny_run)
    assert code == 0, err
    assert f"the run in {tiny_run} is finished" in err and "nothing to train" in err
    assert "| first |" in out and "| second |" in out
    after = {path.name: path.stat().st_mtime_ns for path in tiny_run.iterdir() if path.is_file()}
    assert after == before
    code, out, _ = run_main(capfd, "train", "--resume", tiny_run, "--json")
    assert code == 0 and json.loads(out)["frames"] == json.loads((tiny_run / "eval.json").read_text())["frames"]


def test_ctrl_c_during_training_names_the_folder_to_resume(tmp_path: Path, monkeypatch, capfd) -> None:
    import ncbot.pipelines.train.run as run

    from tests.learning_helpers import write_tiny_config

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(run, "train", interrupted)
    code, _, err = run_main(capfd, "train", write_tiny_config(tmp_path), "--out", tmp_path / "mine")
    assert code == 130
    assert err.strip() == f"ncbot: interrupted (Ctrl-C); continue with ncbot train --resume {tmp_path / 'mine'}"
