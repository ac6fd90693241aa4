"""`ncbot ladder`: how good is a trained agent against more than a random player (issue 6)?

The agent plays its full dialogues in the real env, greedy with its own look-ahead masks, while the simulated
user's game moves come from each opponent of the ladder (``envs.opponents``), from both seats. Scores count a
win 1 and a draw 0.5. The goals of the issue are checked and printed with the table: on 3x3 never lose to
``minimax`` or ``random``; on Ultimate score at least 0.5 against ``mcts:100``.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

DEFAULT_LADDERS = {
    "standard": ["random", "rule", "minimax"],
    "ultimate": ["random", "rule", "mcts:10", "mcts:100", "mcts:300"],
}
SEATS = ("first", "second")
LOOKAHEAD_CHOICES = ("none", "one_step", "k1", "k2", "k3", "k4", "k5")


def resolve_lookahead(name: str, free_move: str) -> str:
    """A `--lookahead` choice -> the mask rule name for this game's rule variant (`k3` -> `k3_open` on
    `open_subgrids`); ValueError naming the allowed choices otherwise."""
    from modules.masks import LOOKAHEAD_RULES

    rule = name.strip()
    if free_move == "open_subgrids" and rule.startswith("k") and not rule.endswith("_open"):
        rule = f"{rule}_open"
    if rule not in LOOKAHEAD_RULES or rule == "variant":
        raise ValueError(f"--lookahead must be one of {', '.join(LOOKAHEAD_CHOICES)}, got {name!r}")
    return rule


def load_robot(checkpoint: str, *, search: int | None = None, lookahead: str | None = None, seed: int = 0):
    """(config, policy, description) of the robot as the ladder plays it.

    How the robot decides is part of what a ladder measures, so it is chosen here and named in the table:
    ``lookahead`` replaces the checkpoint's masks (``none``, ``one_step`` = the paper's, ``k1``..``k5``);
    ``search`` > 0 picks every game move by MCTS guided by the Q-network with that many simulations (dialogue
    acts stay greedy); with both, the search's root skips the moves the k-step rule proves lost (when some
    move survives).
    """
    from modules.masks import lookahead_rule
    from modules.policy import make_policies
    from pipelines.evaluate import load_agent

    if search is not None and search < 1:
        raise ValueError(f"--search must be a positive number of simulations, got {search}")
    config, greedy = load_agent(checkpoint)
    if lookahead is not None:
        config.agent.lookahead = resolve_lookahead(lookahead, config.env.free_move)
        from torchrl.data import Categorical

        qnet = greedy[0]  # the policy chain starts with the Q-network (modules.policy.make_policies)
        n_actions = qnet.module[-1].out_features  # its last Linear has one output per action (modules.qnet.make_qnet)
        greedy = make_policies(qnet, Categorical(n_actions), config.lookahead).greedy
    description = f"greedy Q, masks {config.lookahead}"
    if not search:
        return config, greedy, description
    from modules.guided_mcts import GuidedMCTSPolicy

    mcts = guided_search(config, greedy, search)  # the same loaded Q-network, not a second read of the file
    rule = lookahead_rule(config.lookahead)
    prune = rule if hasattr(rule, "forced_losses") and getattr(rule, "plies", 0) >= 3 else None
    policy = GuidedMCTSPolicy(greedy, mcts, seed, prune=prune)
    return config, policy, f"Q-guided MCTS {search} sims, masks {config.lookahead}"


def run_ladder(checkpoint: str, *, games: int = 200, opponents: list[str] | None = None, seed: int = 0,
               out_dir: str | None = None, progress: bool = True, baseline: bool = False,
               search: int | None = None, lookahead: str | None = None) -> dict[str, Any]:
    """Play every (opponent, seat) pair; write ladder.md / ladder.json / ladder.png; return rows, goals and paths.

    ``baseline`` also plays the agent's look-ahead masks alone (random choice inside them) on the same games,
    so the table shows what learning added beyond the masks. ``search`` / ``lookahead``: how the robot decides
    (``load_robot``); the table header says which.
    """
    import torch

    from envs.opponents import make_opponent
    from pipelines.evaluate import evaluate_agent

    if games < 1:
        raise ValueError(f"--games must be a positive number of games per opponent and seat, got {games}")
    torch.set_num_threads(1)
    register_agent_opponent()
    config, policy, robot = load_robot(checkpoint, search=search, lookahead=lookahead, seed=seed)
    game = config.env.game
    names = list(opponents) if opponents else DEFAULT_LADDERS[game]
    for name in names:  # fail fast, with the registry's message, before any game is played
        make_opponent(name, game=game, free_move=config.env.free_move)
    from pipelines.play import LookaheadOnlyPolicy

    policies = [("agent", policy)]
    if baseline:
        policies.append(("look-ahead only", LookaheadOnlyPolicy(seed, config.lookahead)))
    rows = []
    pairs = [(name, seat, who, chooser) for name in names for seat in SEATS for who, chooser in policies]
    bar = None
    if progress:
        from pipelines.progress import progress_bar

        bar = progress_bar(total=len(pairs), desc="ladder", unit="match")
    for index, (name, seat, who, chooser) in enumerate(pairs):
        if bar is not None:
            bar.set_postfix_str(f"{who} vs {name} ({seat})")
        match_seed = seed + 1000 * (index // len(policies))  # the agent and the baseline meet the same games
        result = evaluate_agent(config, chooser, games=games, seat=seat, seed=match_seed, opponent=name)
        rows.append({
            "policy": who, "opponent": name, "seat": seat, "games": result.games, "win": result.win, "draw": result.draw,
            "loss": result.loss, "score": result.win + 0.5 * result.draw, "task_success": result.task_success,
            "task_success_ci95": result.task_success_ci95, "avg_length": result.avg_length,
        })
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    goals = check_goals(game, rows)
    out = Path(out_dir) if out_dir else _default_out(checkpoint)
    markdown = ladder_markdown(checkpoint, game, config.agent.name, rows, goals, robot=robot)
    files = {
        "markdown": _write_text(out / "ladder.md", markdown),
        "json": _write_text(out / "ladder.json", json.dumps({"checkpoint": str(checkpoint), "game": game,
                                                              "agent": config.agent.name, "robot": robot,
                                                              "search": search or 0, "lookahead": config.lookahead,
                                                              "seed": seed, "rows": rows, "goals": goals}, indent=2)),
        "png": draw_ladder(rows, out / "ladder.png", title=f"{config.agent.name} on {game} ({robot}): score vs opponents"),
    }
    return {"rows": rows, "goals": goals, "markdown": markdown, "files": {k: str(v) for k, v in files.items()}}


def check_goals(game: str, rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The issue's goals that this ladder covers, each with whether it was met."""
    by_opponent: dict[str, list[dict[str, Any]]] = {}
    for row in rows:
        if row.get("policy", "agent") == "agent":
            by_opponent.setdefault(row["opponent"], []).append(row)
    goals = []
    if game == "standard":
        for name in ("random", "minimax"):
            if name in by_opponent:
                losses = sum(round(r["loss"] * r["games"]) for r in by_opponent[name])
                goals.append({"goal": f"never loses to {name}", "met": losses == 0, "value": f"{losses} losses"})
    elif "mcts:100" in by_opponent:
        matches = by_opponent["mcts:100"]
        score = sum(r["score"] * r["games"] for r in matches) / sum(r["games"] for r in matches)
        goals.append({"goal": "score >= 0.5 against mcts:100", "met": score >= 0.5, "value": f"{score:.3f}"})
    return goals


def ladder_markdown(checkpoint: str, game: str, agent: str, rows: list[dict[str, Any]], goals: list[dict[str, Any]],
                    robot: str = "greedy Q, the checkpoint's masks") -> str:
    lines = [f"# Ladder: {agent} ({game}) from `{checkpoint}`", "", f"Robot decides by: {robot}.", "",
             "| robot policy | opponent | robot seat | games | win | draw | loss | score | task success (95% CI) | actions/game |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        low, high = r["task_success_ci95"]
        lines.append(f"| {r.get('policy', 'agent')} | {r['opponent']} | {r['seat']} | {r['games']} | {r['win']:.3f} | {r['draw']:.3f} | {r['loss']:.3f} | "
                     f"{r['score']:.3f} | {r['task_success']:.3f} ({low:.3f}-{high:.3f}) | {r['avg_length']:.1f} |")
    if goals:
        lines += ["", "Goals (issue 6):"]
        lines += [f"- {'met' if g['met'] else 'NOT met'}: {g['goal']} ({g['value']})" for g in goals]
    return "\n".join(lines) + "\n"


def draw_ladder(rows: list[dict[str, Any]], path: Path, title: str) -> Path:
    """Stacked win/draw/loss bars per opponent and seat (what a reader checks first: where does it lose?)."""
    from pipelines.plots import pyplot, save_figure

    plt = pyplot()

    labels = [f"{'' if r.get('policy', 'agent') == 'agent' else 'masks only: '}{r['opponent']}\n"
              f"{'robot first' if r['seat'] == 'first' else 'robot second'}" for r in rows]
    x = range(len(rows))
    fig, ax = plt.subplots(figsize=(max(7.0, 1.3 * len(rows) + 2.0), 4.0))
    wins = [r["win"] for r in rows]
    draws = [r["draw"] for r in rows]
    losses = [r["loss"] for r in rows]
    hatches = [None if r.get("policy", "agent") == "agent" else "//" for r in rows]  # baseline rows hatched
    for heights, bottom, colour, label in ((wins, None, "#2a9d8f", "win"), (draws, wins, "#e9c46a", "draw"),
                                           (losses, [w + d for w, d in zip(wins, draws)], "#e76f51", "loss")):
        for patch, hatch in zip(ax.bar(x, heights, bottom=bottom, color=colour, label=label), hatches):
            patch.set_hatch(hatch)
    ax.plot(list(x), [r["score"] for r in rows], "ko", label="score (win 1, draw 0.5)")
    ax.set_xticks(list(x), labels, fontsize=8)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("fraction of games")
    ax.set_title(title)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    return path


def _default_out(checkpoint: str) -> Path:
    path = Path(checkpoint)
    return path if path.is_dir() else path.parent


def _write_text(path: Path, text: str) -> Path:
    from pipelines.checkpoint import atomic_write_text

    return atomic_write_text(text, path)


# ---------------------------------------------------------------------------------------------- agent:CHECKPOINT
class AgentOpponent:
    """A trained agent as the user's move policy (``agent:CHECKPOINT``), for agent-vs-agent ladders and curricula.

    The agent learnt its Q-network as the robot in the middle of a dialogue, so its game moves are read from
    the feature vector of a typical game turn: its own marks as robot moves, the other side's as human moves,
    the words of "I take this one" / "done", no command, and (temporal features) the last mark at 1.0 and the
    others at 0.5 because the order of earlier marks is not in the board. On top, the paper's one-step
    look-ahead (Algorithm 2), computed with the exact rules: take a winning cell if there is one, never a cell
    after which the other side wins at once (unless every cell is such), else the best Q-value.
    """

    name = "agent"

    def __init__(self, checkpoint: str, game: str, free_move: str, seed: int) -> None:
        import torch

        from envs.rules import make_game
        from modules.guided_mcts import TurnFeatures
        from modules.qnet import make_qnet
        from pipelines.checkpoint import load_checkpoint
        from pipelines.config import config_from_dict

        data = load_checkpoint(checkpoint)
        config = config_from_dict(data["config"])
        if config.env.game != game:
            raise ValueError(f"agent checkpoint {checkpoint!r} plays {config.env.game}, not {game}")
        self.qnet = make_qnet(data["n_features"], data["n_actions"], config.agent.hidden)
        self.qnet.load_state_dict(data["qnet"])
        self.qnet.eval()
        self.features = TurnFeatures(game, config.env.temporal, free_move)
        self.cells = self.features.cells
        self.rules = make_game(game, free_move)
        self.game, self.free_move = game, free_move
        self.generator = torch.Generator().manual_seed(seed)

    def select(self, boards, last_move, legal, player, generator=None, owners=None):
        import torch

        from envs.opponents.lines import subgrid_owners

        rows = boards.shape[0]
        features = self.features.batch(boards, player, last_move)
        with torch.no_grad():
            q = self.qnet.module(features)[:, :self.cells]
        if self.game == "ultimate" and owners is None:
            owners = subgrid_owners(boards)
        cells = torch.zeros(rows, dtype=torch.long)
        for row in torch.nonzero(legal.any(dim=1)).flatten().tolist():
            choices = torch.nonzero(legal[row]).flatten().tolist()
            preferred = self._lookahead(boards[row].tolist(), int(last_move[row]), player, choices,
                                        None if owners is None else owners[row].tolist())
            values = q[row, preferred]
            cells[row] = preferred[int(values.argmax())]
        return cells

    def _lookahead(self, board: list[int], last_move: int, player: int, choices: list[int], owners) -> list[int]:
        """Algorithm 2 on game moves: the winning cells if any, else the cells that do not lose at once."""
        from envs.rules import DRAWN, State

        other = 3 - player
        mover_is_x = board.count(player) == board.count(other)
        to_xo = {0: 0, player: 1 if mover_is_x else 2, other: 2 if mover_is_x else 1}
        subgrids = () if owners is None else tuple(DRAWN if o == 3 else to_xo[o] for o in owners)
        state = State(board=tuple(to_xo[v] for v in board), last_move=last_move, subgrids=subgrids)
        me = "x" if mover_is_x else "o"
        winning, safe = [], []
        for cell in choices:
            try:
                after = self.rules.play(state, cell)
            except ValueError:  # the caller's legal mask rules; the board alone may disagree (see docs)
                safe.append(cell)
                continue
            if self.rules.outcome(after) == me:
                winning.append(cell)
            elif not any(self.rules.outcome(self.rules.play(after, reply)) not in (None, me, "draw")
                         for reply in self.rules.legal(after)):
                safe.append(cell)
        return winning or safe or choices


def register_agent_opponent() -> None:
    """Make ``agent:CHECKPOINT`` a valid opponent name (envs cannot import pipelines, so pipelines registers it)."""
    from envs.opponents import register_opponent

    def factory(arg, *, game, free_move, seed):
        if not arg:
            raise ValueError("opponent 'agent' needs a checkpoint path, e.g. 'agent:runs/default/checkpoint.pt'")
        return AgentOpponent(arg, game, free_move, seed)

    register_opponent("agent", factory, usage="agent:CHECKPOINT")
    register_qmcts_opponent()


# ------------------------------------------------------------------------------------ qmcts:N:CHECKPOINT (issue 6)
def guided_search(config, greedy, simulations: int, free_move: str | None = None):
    """A PUCT search whose priors and values come from an already loaded agent's Q-network."""
    from modules.guided_mcts import GuidedMCTS, TurnFeatures

    free_move = free_move or config.env.free_move
    qnet = greedy[0].module  # the policy chain starts with the Q-network (modules.policy.make_policies)
    features = TurnFeatures(config.env.game, config.env.temporal, free_move)
    return GuidedMCTS(qnet, features, config.env.game, free_move, simulations)


def load_guided_search(checkpoint: str, simulations: int, free_move: str | None = None):
    """(config, GuidedMCTS) of a saved agent: its Q-network gives the priors and values of a PUCT search."""
    from pipelines.evaluate import load_agent

    config, greedy = load_agent(checkpoint)
    return config, guided_search(config, greedy, simulations, free_move)


def load_guided_agent(checkpoint: str, simulations: int, seed: int = 0):
    """(config, policy) for eval / ladder: the agent's greedy dialogue policy with game moves chosen by the search."""
    from modules.guided_mcts import GuidedMCTSPolicy
    from pipelines.evaluate import load_agent

    config, greedy = load_agent(checkpoint)
    return config, GuidedMCTSPolicy(greedy, guided_search(config, greedy, simulations), seed)


def register_qmcts_opponent() -> None:
    """Make ``qmcts:N:CHECKPOINT`` (MCTS guided by a trained agent's Q-network) a valid opponent name."""
    from envs.opponents import register_opponent
    from modules.guided_mcts import QMCTSOpponent, parse_qmcts

    def factory(arg, *, game, free_move, seed):
        simulations, checkpoint = parse_qmcts(arg)
        config, search = load_guided_search(checkpoint, simulations, free_move)
        if config.env.game != game:
            raise ValueError(f"qmcts checkpoint {checkpoint!r} plays {config.env.game}, not {game}")
        return QMCTSOpponent(search, game, free_move, seed)

    register_opponent("qmcts", factory, usage="qmcts:N:CHECKPOINT")
