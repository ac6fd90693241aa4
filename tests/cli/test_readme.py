"""The README stays a five-minute read that is true: the two commands first, a quick start that writes only under
runs/ and says which set-up each step needs, its Python lines run as shown, short lines, no dated history."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text(encoding="utf-8")
#: commands that need an extra the base install (`bash scripts/main.sh`) does not bring
NEEDS_FULL_SETUP = ("ncbot robot ", "ncbot logs to-rerun", "--backend ray")


def block(language: str, after: str) -> str:
    start = README.index(after)
    match = re.search(rf"```{language}\n(.*?)```", README[start:], re.S)
    assert match is not None, f"no {language} block after {after!r}"
    return match.group(1)


def test_the_readme_is_short_and_opens_with_the_two_commands() -> None:
    assert len(README.encode("utf-8")) <= 12 * 1024
    first = block("bash", "# ncbot").strip().splitlines()
    assert [line.split("#")[0].strip() for line in first] == ["bash scripts/main.sh", "bash scripts/test.sh"]
    main = (ROOT / "scripts" / "main.sh").read_text()
    assert "scripts/setup.sh base" in main and "ncbot train" in main and "ncbot eval" in main
    assert "scripts/setup.sh full" in (ROOT / "scripts" / "test.sh").read_text()


def test_lines_and_cells_stay_short_and_nothing_is_dated() -> None:
    long = [line[:60] for line in README.splitlines() if len(line) > (300 if line.startswith("|") else 200)]
    cells = [cell[:60] for line in README.splitlines() if line.startswith("|") for cell in line.split("|")
             if len(cell) > 160]
    assert not long and not cells, (long, cells)
    assert not re.findall(r"20\d\d-\d\d-\d\d", README), "a measurement's date belongs on its results or docs page"


def test_the_quick_start_writes_under_runs_and_names_the_set_up_each_step_needs() -> None:
    quick = block("bash", "## Quick start")
    steps = re.split(r"\n(?=# \d+\. )", quick)
    assert len(steps) >= 5
    for step in steps:
        commands = [line for line in step.splitlines() if line.startswith("ncbot ")]
        for command in commands:
            for output in re.findall(r"(?:--out|-o)\s+(\S+)", command):
                assert output.startswith("runs/"), f"{command!r} writes outside runs/"
            if command.startswith("ncbot vision generate") or command.startswith("ncbot robot render"):
                assert re.search(r"(--out|-o)\s+runs/", command), f"{command!r} writes into the working folder"
        if any(needle in command for command in commands for needle in NEEDS_FULL_SETUP):
            assert "full set-up" in step.splitlines()[0], f"step {step.splitlines()[0]!r} needs the full set-up"


def test_the_python_lines_run_as_shown(tmp_path: Path) -> None:
    code = block("python", "From Python")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, "-c", code + "\nprint(env.batch_size, sorted(td.keys())[:2])"],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith("torch.Size([64])")
