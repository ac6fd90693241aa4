"""The dialogue data budget of `ncbot reproduce budget`: how many example dialogues the act filter, the simulated
user and the agent trained in that simulation need (the title's "a dozen dialogues").

- Filter agreement: the act filter learnt from k of the paper set's example dialogues (``env.dialogue_subset``)
  against the filter of every dialogue we have (24: the paper-sized dozen and our authored dozen), and against the
  dozen's, as the share of the reference's example turns whose allowed acts are the same set under both filters.
- Agents: Proposed + temporal on 3x3 with the paper config, trained and tested in the env learnt from k dialogues
  (the paper trains and tests in one simulated env; the agreement column says how far that env's dialogue is from
  the reference's), ``budget.dialogue_subsets`` subsets per k (subset s trains with seed s, so k = 12 and 24, where
  every subset is the same, still vary by seed), at ``budget.dialogue_games`` training games. Task success and
  dialogue length are the final robot-first test games' (as in the paper table).
"""
from __future__ import annotations

import textwrap
from collections import defaultdict
from pathlib import Path
from typing import Any

DIALOGUE_POINTS = (1, 2, 4, 8, 12, 24)  # 13-24 are ours (authored), envs/data/example_dialogues_paper_extra.yaml
SUBSETS = 3  # seeded subsets per k for the filter agreement (the agents use the budget's dialogue_subsets)
PAPER_DIALOGUES = 12  # the paper's "a dozen dialogues" per game
DIALOGUE_ROW = "standard"  # the dialogue agents' game row: 3x3 (Ultimate would cost ~5x per run)
PAPER_PROPOSED_3X3 = (0.9980, 14.06)  # the paper's Proposed + temporal on 3x3: task success, dialogue length


def filter_agreement(game: str, k: int, seed: int, dialogues: str = "paper", reference: int | None = None) -> float:
    """Share of the reference's example turns whose allowed acts (Pr > 0.001) the filter from a seeded subset of
    ``k`` dialogues allows exactly as the reference's filter does. ``reference``: how many dialogues the reference
    filter learns from (default: every one the set has, 24 for the paper set; 12 = the paper's dozen)."""
    import ncbot.envs.dialogue as dlg

    chosen = dlg.dialogue_set(dialogues)
    everything = len(dlg.example_pool(game, chosen))
    full = dlg.build_dialogue_model(game, dialogues, (reference or everything, 0))
    subset = dlg.build_dialogue_model(game, dialogues, (k, seed))
    same = [bool((full.filter_allowed[c] == subset.filter_allowed[c]).all()) for c in full.example_contexts]
    return sum(same) / len(same)


def dialogue_budget(games: tuple[str, ...]) -> list[dict[str, Any]]:
    """One record per (game, k): the mean agreement over the seeded subsets (a single subset from a dozen up:
    every k <= 12 draws from the dozen, a larger k is the dozen plus k - 12 authored ones)."""
    records = []
    for game in games:
        for k in DIALOGUE_POINTS:
            seeds = 1 if k >= PAPER_DIALOGUES else SUBSETS
            values = [filter_agreement(game, k, seed) for seed in range(seeds)]
            dozen = [filter_agreement(game, k, seed, reference=PAPER_DIALOGUES) for seed in range(seeds)]
            records.append({"game": game, "dialogues": k, "subsets": seeds, "filter_agreement": sum(values) / seeds,
                            "filter_agreement_dozen": sum(dozen) / seeds, "task_success": None, "avg_length": None})
    return records


def plan_dialogue_runs(budget: Any, runs_dir: Path, config: Path) -> list[Any]:
    """The dialogue budget's training runs: Proposed + temporal on 3x3 (paper config, env.dialogues: paper) learnt
    from k example dialogues, k in ``budget.dialogue_points``, ``budget.dialogue_subsets`` subsets each; subset s
    also trains with seed s; ``config``: the 3x3 paper config (`ncbot.pipelines.reproduce.grid.row_config`). Runs go to RUNS_DIR/kNN/seedS
    (resumable like the table's)."""
    from ncbot.pipelines.grid.plan import PlannedRun
    from ncbot.pipelines.config import load_config

    config = Path(config).resolve()
    planned = []
    for k in budget.dialogue_points:
        for seed in range(budget.dialogue_subsets):
            overrides = [f"train.max_games={budget.dialogue_games}", f"eval.games={budget.eval_games}",
                         f"train.eval_every_frames={budget.eval_every_frames[DIALOGUE_ROW]}", "logger.mcap=false",
                         "agent.name=proposed", "env.temporal=true", "env.dialogues=paper",
                         f"env.dialogue_subset.k={k}", f"env.dialogue_subset.seed={seed}", f"train.seed={seed}"]
            load_config(config, overrides)  # a bad config fails here, before any run starts
            planned.append(PlannedRun(name=f"dialogues/k{k:02d}/seed{seed}", config=config, overrides=overrides,
                                      run_dir=runs_dir / f"k{k:02d}" / f"seed{seed}"))
    return planned


def run_dialogue_agents(budget: Any, *, runs_dir: Path, config: Path, cluster: Any) -> dict[str, Any]:
    """Train the unfinished dialogue-budget runs through `ncbot ablate`'s runner on ``cluster`` (a
    `ncbot.pipelines.grid.runner.Cluster`: local processes, Ray or Slurm)."""
    from ncbot.pipelines.grid.runner import execute_runs

    planned = plan_dialogue_runs(budget, Path(runs_dir), config)
    todo = [run for run in planned if not run.finished]
    summary = execute_runs(todo, cluster=cluster, runs_dir=runs_dir, desc="dialogues")
    return {**summary, "skipped": len(planned) - len(todo), "planned": len(planned),
            "unfinished": sorted(run.name for run in planned if not run.finished)}


def agent_budget(runs_dir: Path | None) -> dict[int, dict[str, Any]]:
    """Per k: robot-first task success and dialogue length of the finished dialogue-budget runs, mean and 95 %
    interval over the subsets (the unit is a subset with its training seed; task success on the logit scale, so it
    stays inside [0, 1]: pipelines.reproduce.seed_stats)."""
    from ncbot.pipelines.reproduce.seed_stats import proportion_interval, t_interval
    from ncbot.pipelines.reproduce.table import DEFAULT_GAMES, read_eval

    by_k: dict[int, list[dict[str, Any]]] = defaultdict(list)
    for path in sorted(Path(runs_dir).glob("k*/seed*/eval.json")) if runs_dir is not None else []:
        by_k[int(path.parts[-3][1:])].append(read_eval(path))
    result = {}
    for k, runs in by_k.items():
        games = min(int(r["first"].get("games", DEFAULT_GAMES)) for r in runs)
        success = proportion_interval([r["first"]["task_success"] for r in runs], games)
        length = t_interval([r["first"]["avg_length"] for r in runs])
        result[k] = {"runs": len(runs), "task_success": success.mean, "task_success_ci95": _bounds(success),
                     "avg_length": length.mean, "avg_length_ci95": _bounds(length),
                     "training_games": [r.get("episodes") for r in runs]}
    return result


def _bounds(interval: Any) -> list[float] | None:
    return None if interval.low is None else [interval.low, interval.high]


def dialogue_records(games: tuple[str, ...], dialogue_runs: Path | None) -> list[dict[str, Any]]:
    """The `--json` "dialogues" list: per (game, k) the filter agreement and, on 3x3 once its runs finished, the
    agents' task success and dialogue length (None where not trained)."""
    records = dialogue_budget(games)
    agents = agent_budget(dialogue_runs)
    for record in records:
        if record["game"] == DIALOGUE_ROW and record["dialogues"] in agents:
            record.update(agents[record["dialogues"]])
    return records


def _cell(record: dict[str, Any], key: str, digits: int) -> str:
    if record.get(key) is None:
        return "–"
    bounds = record.get(f"{key}_ci95")
    interval = f" [{bounds[0]:.{digits}f}, {bounds[1]:.{digits}f}]" if bounds else " [n<2]"
    return f"{record[key]:.{digits}f}{interval}"


def dialogue_section(records: list[dict[str, Any]], budget: Any) -> list[str]:
    """The markdown section of data_budget.md for the dialogue budget."""
    lines = ["## Dialogues: example dialogues per game (paper set)", "",
             "Dialogues 1-12 per game are the paper-shaped dozen the env uses by default (`env.dialogues: paper`); "
             "13-24 are ours, authored in the same shape (envs/data/example_dialogues_paper_extra.yaml), used only "
             "for k > 12. Filter agreement: share of the reference's example turns whose allowed acts are the same "
             f"under the filter learnt from k dialogues (mean over {SUBSETS} seeded subsets below a dozen) as under the "
             "reference's: all 24, and the dozen. Agent (3x3 only): Proposed + temporal, paper config, trained and "
             f"tested in the env learnt from k dialogues, {budget.dialogue_subsets} subsets per k (subset s = training "
             f"seed s), {budget.dialogue_games} training games (or 400K steps), robot-first test games; mean [95 % "
             "interval over subsets: Student t, of the per-subset logits for task success]. The paper's 3x3 Proposed + temporal, after 20K games: task success "
             f"{PAPER_PROPOSED_3X3[0]}, length {PAPER_PROPOSED_3X3[1]}.", "",
             "| game | dialogues | filter subsets | filter agreement (all 24) | (the dozen) | agent runs | task success | "
             "dialogue length |", "|---|---|---|---|---|---|---|---|"]
    for r in records:
        lines.append(f"| {r['game']} | {r['dialogues']} | {r['subsets']} | {r['filter_agreement']:.3f} | "
                     f"{r['filter_agreement_dozen']:.3f} | {r.get('runs', 0)} | {_cell(r, 'task_success', 3)} | "
                     f"{_cell(r, 'avg_length', 2)} |")
    return lines


def plot_dialogues(records: list[dict[str, Any]], path: Path, label: str) -> Path:
    """data_budget_dialogues.png: filter agreement, the agents' task success and dialogue length against k."""
    from ncbot.pipelines.plots import pyplot, save_figure

    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    for game in sorted({r["game"] for r in records}):
        rows = [r for r in records if r["game"] == game]
        ks = [r["dialogues"] for r in rows]
        axes[0].plot(ks, [r["filter_agreement"] for r in rows], marker="o", label=f"{game}: vs all 24")
        axes[0].plot(ks, [r["filter_agreement_dozen"] for r in rows], marker="x", linestyle=":",
                     label=f"{game}: vs the dozen")
    agents = [r for r in records if r["game"] == DIALOGUE_ROW and r.get("task_success") is not None]
    for ax, key, paper, name in ((axes[1], "task_success", PAPER_PROPOSED_3X3[0], "task success (robot first)"),
                                 (axes[2], "avg_length", PAPER_PROPOSED_3X3[1], "dialogue length (acts)")):
        if agents:
            means = [r[key] for r in agents]
            errors = [[m - (r[f"{key}_ci95"] or [m, m])[0] for m, r in zip(means, agents)],
                      [(r[f"{key}_ci95"] or [m, m])[1] - m for m, r in zip(means, agents)]]
            ax.errorbar([r["dialogues"] for r in agents], means, yerr=errors, marker="o", capsize=3,
                        label="3x3 Proposed + temporal (95 % CI)")
        else:
            ax.text(0.5, 0.5, "no finished dialogue-budget runs", ha="center", transform=ax.transAxes)
        ax.axhline(paper, color="tab:red", linestyle=":", label="paper, after 20K games")
        ax.set_ylabel(name)
    axes[0].set_ylabel("act filter agreement")
    axes[0].set_ylim(0, 1.02)
    axes[1].set_ylim(0, 1.05)
    axes[2].set_ylim(bottom=0)
    for ax in axes:
        ax.axvline(PAPER_DIALOGUES, color="grey", linestyle="--", label="paper: a dozen")
        ax.set_xscale("log", base=2)
        ax.set_xlim(0.8, 30)
        ax.set_xticks(DIALOGUE_POINTS, [str(k) for k in DIALOGUE_POINTS])
        ax.set_xlabel("example dialogues per game (13-24: ours)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(textwrap.fill(label, 180), fontsize=7)
    fig.tight_layout()
    return save_figure(fig, path)
