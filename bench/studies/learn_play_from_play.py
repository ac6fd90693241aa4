"""Play that learns from play, measured: N games against a simulated person, the robot's agent learning after each
one (`ncbot.pipelines.online`, the games logged to MCAP and read back) against the same games played frozen.

    python bench/studies/learn_play_from_play.py CKPT --person rule --games 50 --seeds 0,1,2,3,4 \
        --out runs/learn_play [--updates 100] [--test-games 1000] [--no-gate]

Per seed: the frozen agent and the learning one play games 0..N-1 (seats alternating, game g's env seed
1000 x seed + g: the person's dice are the same for both); afterwards both agents play `--test-games` test games
against the person and against the random user (both seats, seed 8,000,009). Writes OUT/learn_play.json (every
game's outcome, per seed and mode, the test games, each learning update's CPU seconds, whether it was kept and
which of the gate's checks refused it, the kept agent's task success against the model of the person before each
update) and OUT/learn_play.png (wins and losses per game over the sequence, mean over seeds). A learning sequence whose folder holds all its learned
games is read back, not played again, so the study resumes after a stop (the frozen games are replayed). No
rendering: what play learns does not depend on the camera (the reader has its own study,
bench/studies/learn_reader_from_play.py).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from ncbot.logs import EpisodeLogger  # noqa: E402
from ncbot.pipelines.online import agent_parts  # noqa: E402
from ncbot.pipelines.online.learning import LearnSettings, PersonLearning  # noqa: E402
from ncbot.pipelines.online.play_learner import PlayLearning  # noqa: E402
from ncbot.pipelines.online.robot_games import last_game  # noqa: E402
from ncbot.pipelines.online.simulated import play_logged_game  # noqa: E402
from ncbot.pipelines.online.summary import TEST_SEED  # noqa: E402
from ncbot.pipelines.evaluate.games import wilson_interval  # noqa: E402
from ncbot.pipelines.plots import pyplot, save_figure  # noqa: E402
from ncbot.pipelines.reproduce.seed_stats import proportion_interval, t_interval  # noqa: E402


def run_sequence(checkpoint: Path, person: str, games: int, seed: int, folder: Path, learn: bool,
                 updates: int, gate: bool = True) -> tuple[list[str], list[dict], object]:
    """The outcomes of one sequence of games, what each learning update did (`PlayUpdate.to_dict`: its gate's
    figures, kept or not, CPU seconds), and the final policy."""
    settings = LearnSettings(reader=None, play=PlayLearning(seed=seed, updates=updates, gate=gate))
    learning = PersonLearning.open(folder / "learning", settings, checkpoint=checkpoint)
    if learn and learning.games >= games:  # a finished learning sequence is not played again
        done = learning.per_game[:games]
        return [e["outcome"] for e in done], [e["play"] for e in done], learning.play
    if learn and learning.games:
        raise SystemExit(f"{folder} holds {learning.games} of {games} learned games; remove it to play them again")
    config, policy = learning.play.config, learning.play.policy
    outcomes, learned_plays = [], []
    with EpisodeLogger(folder / "log") as log:
        for game in range(games):
            game_seed = 1000 * seed + game
            outcome = play_logged_game(config, policy, log, opponent=person, seed=game_seed,
                                       first="robot" if game % 2 == 0 else "human", agent_name="study")
            outcomes.append(outcome)
            if learn:
                log.flush()
                learned = learning.learn([], [], True, last_game(folder / "log", game_seed), {"outcome": outcome})
                learned_plays.append(learned["play"])
    return outcomes, learned_plays, learning.play


def rolled_back_by(update: dict) -> str | None:
    """Which of the gate's checks refused an update: "random user" (task success below the starting agent's),
    "person model" (below the kept agent's against the model of the person), "both"; None when kept or not run."""
    if not update["updated"] or update["kept"]:
        return None
    settings = PlayLearning()
    random_user = update["gate_task_success"] < update["start_task_success"] - settings.gate_tolerance
    person_model = update["person_task_success"] < update["kept_person_task_success"]
    return "both" if random_user and person_model else "random user" if random_user else "person model"


def tested(play, person: str, games: int) -> dict:
    result = {}
    for opponent in (person, "random"):
        t = agent_parts.test_games(play.config, play.policy, games, TEST_SEED, opponent=opponent)
        result[opponent] = {"win": round(t.win, 4), "draw": round(t.draw, 4), "loss": round(t.loss, 4),
                            "task_success": round(t.task_success, 4)}
    return result


def interval(values: list[float], games: int | None = None) -> dict:
    """Mean over seeds with its 95 % Student-t interval (bounds None with one seed); of a rate over `games` test
    games, on the logit scale (`proportion_interval`), so it stays inside [0, 1]."""
    found = t_interval(values) if games is None else proportion_interval(values, games)
    return {"mean": round(found.mean, 4), "low": None if found.low is None else round(found.low, 4),
            "high": None if found.high is None else round(found.high, 4), "seeds": found.n}


def summarise(data: dict) -> dict:
    """The headline figures: losses and wins per sequence (per seed, their t interval over seeds, and the pooled
    loss rate's Wilson interval over every game), the learning minus frozen losses of the same seed, the test games
    afterwards, and the CPU seconds of a learning update."""
    runs, summary = data["runs"], {}
    for mode in ("frozen", "learning"):
        losses = [run[mode]["outcomes"].count("loss") for run in runs]
        wins = [run[mode]["outcomes"].count("win") for run in runs]
        games = sum(len(run[mode]["outcomes"]) for run in runs)
        summary[mode] = {"losses_per_seed": losses, "losses": interval(losses), "wins_per_seed": wins,
                         "wins": interval(wins),
                         "loss_rate_wilson": [round(b, 4) for b in wilson_interval(sum(losses), games)],
                         "tests": {opponent: {key: interval([run[mode]["tests"][opponent][key] for run in runs],
                                                            data["test_games"])
                                              for key in ("task_success", "win", "loss")}
                                   for opponent in runs[0][mode]["tests"]}}
    for outcome, name in (("loss", "losses"), ("win", "wins")):
        summary[f"{name}_learning_minus_frozen"] = interval([run["learning"]["outcomes"].count(outcome) -
                                                                run["frozen"]["outcomes"].count(outcome)
                                                                for run in runs])
    learned = [run["learning"] for run in runs]
    summary["updates_kept_per_seed"] = [len(run["updates_kept"]) for run in learned]
    summary["rolled_back_by"] = {reason: sum(run["rolled_back_by"].count(reason) for run in learned)
                                 for reason in ("random user", "person model", "both")}
    cpu = [c for run in runs for c in run["learning"]["update_cpu_seconds"]]
    summary["update_cpu_seconds"] = {"mean": round(float(np.mean(cpu)), 3), "median": round(float(np.median(cpu)), 3),
                                     "max": round(max(cpu), 3), "updates": len(cpu)}
    return summary


def draw(data: dict, path: Path) -> Path:
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), sharex=True)
    for mode, colour in (("frozen", "tab:gray"), ("learning", "tab:purple")):
        for ax, outcome in zip(axes, ("win", "loss")):
            rows = np.array([[o == outcome for o in run[mode]["outcomes"]] for run in data["runs"]], float)
            games = np.arange(rows.shape[1])
            cumulative = rows.cumsum(axis=1)
            ax.plot(games, cumulative.mean(axis=0), color=colour, label=f"{mode} (mean of {len(rows)} seeds)")
            ax.fill_between(games, cumulative.min(axis=0), cumulative.max(axis=0), color=colour, alpha=0.2)
            ax.set_title(f"{'wins' if outcome == 'win' else 'losses'} against the {data['person']} person, so far")
            ax.set_xlabel("game")
    axes[0].set_ylabel("games (band: lowest to highest seed)")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("checkpoint", type=Path)
    parser.add_argument("--person", default="rule")
    parser.add_argument("--games", type=int, default=50)
    parser.add_argument("--seeds", default="0,1,2,3,4")
    parser.add_argument("--updates", type=int, default=PlayLearning().updates)
    parser.add_argument("--test-games", type=int, default=1000)
    parser.add_argument("--no-gate", action="store_true", help="keep every update unchecked (what the gate refuses)")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    started = time.time()
    data = {"person": args.person, "games": args.games, "checkpoint": str(args.checkpoint), "updates": args.updates,
            "test_games": args.test_games,
            "settings": PlayLearning(updates=args.updates, gate=not args.no_gate).__dict__, "runs": []}
    for seed in [int(s) for s in args.seeds.split(",")]:
        run = {"seed": seed}
        for mode in ("frozen", "learning"):
            outcomes, learned, play = run_sequence(args.checkpoint, args.person, args.games, seed,
                                                   args.out / f"seed{seed}" / mode, mode == "learning", args.updates,
                                                   not args.no_gate)
            run[mode] = {"outcomes": outcomes, "update_cpu_seconds": [u["cpu_seconds"] for u in learned],
                         "updates_kept": [u["game"] for u in learned if u["kept"]],
                         "rolled_back_by": [rolled_back_by(u) for u in learned],
                         "person_model_task_success": [u["kept_person_task_success"] for u in learned],
                         "tests": tested(play, args.person, args.test_games)}
            print(f"seed {seed} {mode}: {''.join(o[0] for o in outcomes)}", file=sys.stderr, flush=True)
        data["runs"].append(run)
    data["wall_seconds"] = round(time.time() - started, 1)
    data["summary"] = summarise(data)
    print(json.dumps(data["summary"], indent=1))
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "learn_play.json").write_text(json.dumps(data, indent=1))
    draw(data, args.out / "learn_play.png")
    print(f"wrote {args.out / 'learn_play.json'} and {args.out / 'learn_play.png'}")


if __name__ == "__main__":
    main()
