"""`ncbot reproduce`: the paper's table, its claims and the data budgets in one command, at a named budget.

Why one command: the paper's findings need dozens of runs with the faithful options on (pipelines/configs/paper/)
and a fixed protocol (seeds, games, test games). `table` writes an ablation grid for the budget and runs it
through the same runner as `ncbot ablate` (pipelines/train/ablate.py: parallel processes, finished runs skipped, a
killed run resumed from its checkpoint), then `ncbot.pipelines.reproduce.table.write_report` writes the table and the claims.
`budget` reads the data budgets off those runs and the example dialogues, and trains the dialogue-budget agents
(pipelines/reproduce/budget.py). `vision` trains the cell classifier on N labelled cells and runs the paper's
vision experiments (pipelines/reproduce/vision.py); it needs no RL runs. `--backend ray [--address HOST:PORT]`
runs every run as a Ray task (pipelines/train/ray_backend.py: the runs folder must be shared by every node, checked
before any run starts).

Budgets: `full` is the paper's protocol (5 seeds, 20K games or 400K steps, 3000 test games, every game row);
`quick` is a smoke version that fits in < 30 min on 2 cores, and says so in every file it writes.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from ncbot.fileio import atomic_write_text

PAPER_CONFIGS = Path(__file__).parents[1] / "configs" / "paper"
PARTS = ("table", "vision", "budget", "all")
# the paper's three agents and the uniform choice inside Proposed's masks (no learning: what learning adds)
AGENTS = ("uniform", "dqn_original", "dqn_variant", "proposed")


@dataclass(frozen=True)
class Budget:
    """How much a reproduction spends: seeds, game rows, the training cap and the test games."""

    name: str
    seeds: int
    rows: tuple[str, ...]
    max_games: dict[str, int]  # training games per game row (the runs stop at 400K frames if that comes first)
    eval_games: int  # final test games per seat
    eval_every_frames: dict[str, int]  # periodic evaluations: the points of the games-budget curve
    game_points: tuple[int, ...]  # training games at which the games-budget curve is read
    label: str  # one line every output of this budget starts with
    extra_overrides: tuple[str, ...] = field(default_factory=tuple)
    # the dialogue data budget's agents (pipelines/reproduce/budget.py): Proposed + temporal on 3x3 per k example
    # dialogues, this many subsets (each its own training seed) per k, capped at this many training games
    dialogue_subsets: int = 2
    dialogue_games: int = 1_000
    dialogue_points: tuple[int, ...] = (1, 2, 4, 8, 12, 24)  # k of the agents (the filter agreement: always all six)


BUDGETS = {
    "full": Budget(
        name="full", seeds=5, rows=("standard", "ultimate100", "ultimate150"),
        max_games={"standard": 20_000, "ultimate100": 20_000, "ultimate150": 20_000}, eval_games=3000,
        eval_every_frames={"standard": 5_000, "ultimate100": 20_000, "ultimate150": 20_000},
        game_points=(1_000, 2_000, 5_000, 10_000, 20_000),
        label="Budget full: the paper's protocol (5 seeds a cell, more where a cell's folder holds more: see the "
              "seeds column; 20K games or 400K steps, 3000 test games per seat); dialogue budget: 5 subsets x 5K "
              "games per k.",
        dialogue_subsets=5, dialogue_games=5_000,
    ),
    "quick": Budget(
        name="quick", seeds=2, rows=("standard", "ultimate100"),
        max_games={"standard": 2_000, "ultimate100": 600}, eval_games=500,
        eval_every_frames={"standard": 5_000, "ultimate100": 20_000},
        game_points=(500, 1_000, 2_000),
        label="QUICK BUDGET (smoke run, not the paper's protocol): 2 seeds, 2K training games on 3x3 and 600 on "
              "Ultimate (100), 500 test games per seat, no Ultimate (150); claims cannot be decided (< 5 seeds); "
              "dialogue budget: 2 subsets x 1K games per k. Run `--budget full` for the paper's numbers.",
        dialogue_subsets=2, dialogue_games=1_000,
    ),
}


def budget_of(name: str) -> Budget:
    """The budget called ``name``; ValueError naming the choices otherwise."""
    try:
        return BUDGETS[name]
    except KeyError:
        raise ValueError(f"--budget must be one of {', '.join(BUDGETS)}; got {name!r}") from None


def row_config(row: str, configs: Path = PAPER_CONFIGS) -> Path:
    """The paper config a game row's grid cells start from (agent and temporal are set per cell)."""
    path = configs / f"{row}_proposed_temporal.yaml"
    if not path.is_file():
        raise FileNotFoundError(f"paper config {str(path)!r} not found (expected one per game row in {configs})")
    return path


def write_grid(budget: Budget, runs_dir: Path, configs: Path = PAPER_CONFIGS) -> Path:
    """The `ncbot ablate` grid of this budget, written into its runs folder (so the runs can be redone by hand)."""
    suites = {}
    for row in budget.rows:
        overrides = [f"train.max_games={budget.max_games[row]}", f"eval.games={budget.eval_games}",
                     f"train.eval_every_frames={budget.eval_every_frames[row]}", "logger.mcap=false",
                     *budget.extra_overrides]
        suites[row] = {"config": str(row_config(row, configs).resolve()), "overrides": overrides}
    grid = {
        "runs_dir": str(runs_dir),
        "suites": {"paper": suites},
        "grid": {"suite": ["paper"], "game": list(budget.rows), "agent": list(AGENTS), "temporal": [False, True],
                 "lookahead": [None]},
        "baselines_with_temporal": False,
    }
    path = runs_dir / "grid.yaml"
    runs_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_text(f"# {budget.label}\n# Written by `ncbot reproduce`; rerun with `ncbot ablate {path} "
                      f"--seeds {budget.seeds}`.\n" + yaml.safe_dump(grid, sort_keys=False), path)
    return path


def labelled(path: Path, budget: Budget, progress: str | None = None) -> None:
    """Put the budget's label (and, for a partial report, how far the runs are) under the first line (the title)
    of a markdown file written by another module."""
    lines = path.read_text().splitlines(keepends=True)
    label = [f"> {budget.label}\n"] + ([">\n", f"> {progress}\n"] if progress else [])
    atomic_write_text("".join(lines[:1] + ["\n", *label] + lines[1:]), path)


#: Agent cells per game row: the two baselines without temporal features, the proposed agent with and without.
CELLS_PER_ROW = len(AGENTS) + 1


def runs_progress(budget: Budget, runs_dir: Path) -> tuple[int, int]:
    """(finished, planned) table runs of this budget in its runs folder (finished = eval.json written)."""
    finished = sum(1 for row in budget.rows for path in (runs_dir / "paper" / row).glob("*/seed*/eval.json")
                   if int(path.parent.name.removeprefix("seed")) < budget.seeds)
    return finished, budget.seeds * len(budget.rows) * CELLS_PER_ROW


def run_grid(budget: Budget, *, runs_dir: Path, workers: int, backend: str,
             configs: Path = PAPER_CONFIGS, address: str | None = None) -> dict[str, Any]:
    """Run the budget's grid through `ncbot ablate`'s runner: finished runs skipped, killed ones resumed."""
    from ncbot.pipelines.train.ablate import run_ablation

    grid = write_grid(budget, runs_dir, configs)
    return run_ablation(grid, seeds=budget.seeds, workers=workers, backend=backend, out=runs_dir, address=address)


def write_table_report(budget: Budget, *, runs_dir: Path, out: Path, command: str) -> dict[str, Any]:
    """out/paper_table.md and out/paper_claims.md (pipelines.reproduce.table.write_report), each labelled with the budget,
    and marked PARTIAL (with how many runs are finished) while the budget's runs are not all done."""
    from ncbot.pipelines.reproduce.table import write_report

    out.mkdir(parents=True, exist_ok=True)
    table, claims = out / "paper_table.md", out / "paper_claims.md"
    report = write_report(runs_dir, table, claims, command=command)
    finished, planned = runs_progress(budget, runs_dir)
    progress = None if finished >= planned else (
        f"PARTIAL: {finished} of the budget's {planned} runs finished; rows with fewer seeds than the budget's "
        f"{budget.seeds} are shown but decide no claim. Rerun the budget's command to finish (finished runs are skipped).")
    for path in (table, claims):
        labelled(path, budget, progress)
    return {"table": str(table), "claims_file": str(claims), "finished_runs": finished, "planned_runs": planned,
            **report.to_dict()}


def reproduce(part: str, budget_name: str | Budget, *, out: str | Path = "results", runs: str | Path = "runs/reproduce",
              workers: int = 2, backend: str = "local", command: str = "ncbot reproduce",
              configs: Path = PAPER_CONFIGS, address: str | None = None, report_only: bool = False) -> dict[str, Any]:
    """`ncbot reproduce PART --budget NAME`: the runs, then the table and claims (table), the data budgets
    (budget; its games curve reads the same runs, its dialogue curve trains agents on k example dialogues in
    RUNS/dialogues-NAME), the vision experiments and budget (vision: no RL runs), or all of them (all).
    ``backend="ray"``: every RL run a Ray task (``address``: a cluster's head). ``report_only`` (table only):
    no run starts; the table and claims are written from the runs finished so far (a long `full` can be looked
    at while it runs), marked PARTIAL until every run is done."""
    if part not in PARTS:
        raise ValueError(f"part must be one of {', '.join(PARTS)}; got {part!r}")
    budget = budget_name if isinstance(budget_name, Budget) else budget_of(budget_name)
    if report_only:
        if part != "table":
            raise ValueError(f"--report-only writes the table and claims from finished runs: use it with the part "
                             f"'table', not {part!r}")
        runs_dir = Path(runs) / budget.name
        if not runs_dir.is_dir():
            raise ValueError(f"--report-only: no runs folder {str(runs_dir)!r} (expected the --runs folder of an "
                             f"earlier `ncbot reproduce table --budget {budget.name}`)")
        return {"budget": budget.name, "label": budget.label, "command": command,
                "table": write_table_report(budget, runs_dir=runs_dir, out=Path(out), command=command)}
    if workers <= 0:
        raise ValueError(f"--workers must be positive, got {workers}")
    from ncbot.pipelines.train.ablate import check_backend

    check_backend(backend, workers, address)  # before any folder is written
    out, runs_dir = Path(out), Path(runs) / budget.name
    result: dict[str, Any] = {"budget": budget.name, "label": budget.label, "command": command}
    if part in ("vision", "budget", "all"):  # the vision trainings in parallel; the vision files (vision, all)
        from ncbot.pipelines.reproduce.vision import run_vision_part

        result.update(run_vision_part(part, budget, runs_dir=runs_dir, out=out, command=command, workers=workers))
        if part == "vision":
            return result
    result["runs"] = run_grid(budget, runs_dir=runs_dir, workers=workers, backend=backend, configs=configs,
                              address=address)
    if part in ("table", "all"):
        result["table"] = write_table_report(budget, runs_dir=runs_dir, out=out, command=command)
    if part in ("budget", "all"):
        from ncbot.pipelines.reproduce.budget import write_budget_report
        from ncbot.pipelines.reproduce.dialogues import run_dialogue_agents

        dialogue_runs = Path(runs) / f"dialogues-{budget.name}"
        result["dialogue_runs"] = run_dialogue_agents(budget, runs_dir=dialogue_runs,
                                                      config=row_config("standard", configs), workers=workers,
                                                      backend=backend, address=address)
        result["budget_report"] = write_budget_report(budget, runs_dir=runs_dir, out=out, command=command,
                                                      dialogue_runs=dialogue_runs)
    return result
