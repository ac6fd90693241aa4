"""The runs of "The remaining gaps" (docs/reproduction.md): which runs, with which overrides and seeds, and which
evaluations each test reads, fixed as data before any of them ran.

Why data and not an `ncbot ablate` grid: the gaps need new seeds disjoint from the published ones (seeds 12-54, the
published runs hold 0-11), checkpoints kept and evaluated, and logged test games, which a grid of seeds 0..N-1 does
not give. Every run is still `ncbot train` on a shipped paper config, in the layout `ncbot table` reads
(RUNS/<question>/<game row>/<agent cell>/seed<N>/).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

PAPER_CONFIGS = Path(__file__).parents[1] / "configs" / "paper"
FINAL_EVAL_SEED_OFFSET = 2 * 1_000_003  # the final evaluation's games: seed + this (pipelines/train/loop.py)
ACTS_GAMES, ACTS_SEED = 500, 11  # the logged test games of (b) and (c), as "Where the trained agents' acts go"
CHECKPOINT_GAMES = 3000


def full_budget(row: str) -> tuple[str, ...]:
    """The overrides `ncbot reproduce table --budget full` gives a cell (pipelines/reproduce/grid.py's BUDGETS)."""
    from ncbot.pipelines.reproduce.grid import BUDGETS

    every = BUDGETS["full"].eval_every_frames[row]
    return ("train.max_games=20000", "eval.games=3000", f"train.eval_every_frames={every}", "logger.mcap=false")


# the screening's single readings (pipelines/configs/screening.yaml), for (c)
READINGS = {
    "never": ("env.taken_squares=never", "env.misread_rate=null"),
    "compact": ("env.dialogues=compact",),
    "earlier_never": ("env.taken_squares=never", "env.misread_rate=null", "env.win_set=wins_and_threats",
                      "env.dialogues=compact"),
}
CELL_CONFIGS = {"dqn_original-notemporal": "original", "dqn_variant-notemporal": "variant",
                "proposed-notemporal": "proposed", "proposed-temporal": "proposed_temporal"}


@dataclass(frozen=True)
class CheckpointEval:
    """Evaluate a checkpoint of the run as its final evaluation is evaluated (3000 games, the final seed), robot
    first (and second with ``both_seats``); ``frames``: one periodic checkpoint, or None for every one kept."""

    frames: int | None = None
    both_seats: bool = False


@dataclass(frozen=True)
class ActsEval:
    """500 robot-first test games logged to MCAP (``ncbot eval --out``) for `ncbot logs acts` and the reward
    sources; ``frames``: a periodic checkpoint instead of the final one."""

    frames: int | None = None


@dataclass(frozen=True)
class GapRun:
    question: str  # the first folder level, a suite name for `ncbot table`
    row: str  # standard | ultimate100 | ultimate150
    cell: str  # agent cell, as `ncbot ablate` names them
    seed: int
    overrides: tuple[str, ...]
    evaluations: tuple[CheckpointEval | ActsEval, ...] = ()

    @property
    def name(self) -> str:
        return f"{self.question}/{self.row}/{self.cell}/seed{self.seed}"

    @property
    def config(self) -> Path:
        return PAPER_CONFIGS / f"{self.row}_{CELL_CONFIGS[self.cell]}.yaml"

    def folder(self, runs: Path) -> Path:
        return Path(runs) / self.name

    @property
    def part(self) -> str:
        """The question of docs/reproduction.md this run belongs to, (a) to (e)."""
        if self.question == "paper":
            return "(e)" if self.row == "ultimate150" else "(b)"
        return {"steps800k": "(a)", "offered": "(d)"}.get(self.question, "(c)")


def plan() -> list[GapRun]:
    """Every run in the order the queue trains them: (d), (e), (a), (b), (c) (docs/reproduction.md)."""
    runs: list[GapRun] = []
    # (d) 3x3 DQN-Original with every square offered
    for seed in range(50, 55):
        runs.append(GapRun("offered", "standard", "dqn_original-notemporal", seed,
                           full_budget("standard") + ("env.taken_squares=offered",)))
    # (e) Ultimate (150), both Proposed arms, every 50K-frame checkpoint kept and evaluated; seed 12's logged too
    for seed in range(12, 17):
        for cell in ("proposed-temporal", "proposed-notemporal"):
            extra = (ActsEval(),) if seed == 12 else ()
            runs.append(GapRun("paper", "ultimate150", cell, seed, full_budget("ultimate150") + ("checkpoint.keep=8",),
                               (CheckpointEval(), *extra)))
    # (a) Ultimate (100) Proposed + temporal at 800K frames; its 400K checkpoint evaluated as a paper-mode run
    for seed in range(20, 26):
        extra = (ActsEval(400_000),) if seed == 20 else ()
        runs.append(GapRun("steps800k", "ultimate100", "proposed-temporal", seed,
                           full_budget("ultimate100") + ("collector.total_frames=800000", "checkpoint.keep=16"),
                           (CheckpointEval(400_000, both_seats=True), *extra)))
    # (b) one seed of the paper-mode cells the other questions do not train, test games logged
    paper_cells = {"standard": tuple(CELL_CONFIGS),
                   "ultimate100": ("dqn_original-notemporal", "dqn_variant-notemporal", "proposed-notemporal")}
    for row, cells in paper_cells.items():
        for cell in cells:
            runs.append(GapRun("paper", row, cell, 30, full_budget(row), (ActsEval(),)))
    # (c) Proposed + temporal under three screened readings, test games logged
    for reading, overrides in READINGS.items():
        runs.append(GapRun(reading, "ultimate100", "proposed-temporal", 40, full_budget("ultimate100") + overrides,
                           (ActsEval(),)))
    return runs
