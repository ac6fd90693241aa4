"""Trained agents as the pipelines play them: loaded from a checkpoint, as the robot or as the user's opponent.

`load_agent` gives the greedy policy with the masks the agent trained with; `load_robot` lets a ladder choose how
the robot decides (other masks, Q-guided MCTS); `AgentOpponent` and the ``qmcts`` opponent put a trained agent in
the user's seat (``envs`` cannot import ``pipelines``, so `register_agent_opponent` adds those names to the
opponent registry). Light to import: torch and the env load inside the functions.
"""
from __future__ import annotations

from pathlib import Path

LOOKAHEAD_CHOICES = ("none", "one_step", "k1", "k2", "k3", "k4", "k5")


def check_value_option(value: str | None, search: int | None) -> None:
    """``--value`` before anything loads: it needs ``--search`` (it scores the search's leaves) and an existing file."""
    if value is None:
        return
    if not search:
        raise ValueError("--value scores the leaves of the search: give --search N too")
    if not Path(value).is_file():
        raise FileNotFoundError(f"--value {value!r} not found (expected a value.pt written by ncbot train-value)")


def load_agent(checkpoint_path, *, device: str = "cpu"):
    """(config, greedy policy) of a saved agent: the same masks as in training. `device` (auto | cpu | cuda |
    cuda:N): where its network runs; the evaluation hands it the env's CPU TensorDicts (modules.device.on_device).

    An agent with `agent.memory` reads its hidden state from the env: every caller steps its env wrapped by
    `ncbot.modules.networks.recurrent.memory_env` (evaluation, exact evaluation, `ncbot play`, the robot games), which is
    the env unchanged for the MLP."""
    from ncbot.modules.device import resolve_device
    from ncbot.modules.policies.policy import make_policies
    from ncbot.modules.networks.recurrent import make_agent_qnet
    from ncbot.pipelines.checkpoint import load_agent_checkpoint
    from torchrl.data import Categorical

    config, data = load_agent_checkpoint(checkpoint_path)  # keys, config and weight shapes checked: one-line errors
    qnet = make_agent_qnet(data["n_features"], data["n_actions"], config.agent)  # agent.memory's network or the MLP
    qnet.load_state_dict(data["qnet"])
    qnet.eval()
    where = resolve_device(device)
    if where.type != "cpu":
        qnet.to(where)
    policies = make_policies(qnet, Categorical(data["n_actions"]), config.lookahead, all_negative=config.agent.all_negative,
                             device=where)
    return config, policies.greedy


def resolve_lookahead(name: str, free_move: str) -> str:
    """A `--lookahead` choice -> the mask rule name for this game's rule variant (`k3` -> `k3_open` on
    `open_subgrids`); ValueError naming the allowed choices otherwise."""
    from ncbot.modules.policies.masks import LOOKAHEAD_RULES

    rule = name.strip()
    if free_move == "open_subgrids" and rule.startswith("k") and not rule.endswith("_open"):
        rule = f"{rule}_open"
    if rule not in LOOKAHEAD_RULES or rule == "variant":
        raise ValueError(f"--lookahead must be one of {', '.join(LOOKAHEAD_CHOICES)}, got {name!r}")
    return rule


def load_robot(checkpoint: str, *, search: int | None = None, lookahead: str | None = None, seed: int = 0,
               value: str | None = None):
    """(config, policy, description) of the robot as the ladder plays it.

    How the robot decides is part of what a ladder measures, so it is chosen here and named in the table:
    ``lookahead`` replaces the checkpoint's masks (``none``, ``one_step`` = the paper's, ``k1``..``k5``);
    ``search`` > 0 picks every game move by MCTS guided by the Q-network with that many simulations (dialogue
    acts stay greedy); with both, the search's root skips the moves the k-step rule proves lost (when some
    move survives). ``value``: a value network (``ncbot train-value``) scores the search's leaves.
    """
    from ncbot.modules.policies.masks import lookahead_rule
    from ncbot.modules.policies.policy import make_policies

    if search is not None and search < 1:
        raise ValueError(f"--search must be a positive number of simulations, got {search}")
    check_value_option(value, search)
    config, greedy = load_agent(checkpoint)  # the ladder plays it through evaluate_agent
    if search:
        from ncbot.modules.networks.recurrent import require_feedforward

        require_feedforward(config, "--search")
    if lookahead is not None:  # the masks read the env's board keys, not the network: any agent.memory
        config.agent.lookahead = resolve_lookahead(lookahead, config.env.free_move)
        from torch import nn
        from torchrl.data import Categorical

        qnet = greedy[0]  # the policy chain starts with the Q-network (modules.policies.policy.make_policies)
        n_actions = [layer for layer in qnet.modules() if isinstance(layer, nn.Linear)][-1].out_features  # the head
        greedy = make_policies(qnet, Categorical(n_actions), config.lookahead, all_negative=config.agent.all_negative).greedy
    description = f"greedy Q, masks {config.lookahead}"
    if not search:
        return config, greedy, description
    from ncbot.modules.search.guided_mcts import GuidedMCTSPolicy

    mcts = guided_search(config, greedy, search, value=value)  # the loaded Q-network, not a second read of the file
    rule = lookahead_rule(config.lookahead)
    prune = rule if hasattr(rule, "forced_losses") and getattr(rule, "plies", 0) >= 3 else None
    policy = GuidedMCTSPolicy(greedy, mcts, seed, prune=prune)
    leaves = f", leaves by value net {Path(value).name}" if value else ""
    return config, policy, f"Q-guided MCTS {search} sims{leaves}, masks {config.lookahead}"


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

        from ncbot.envs.games import make_game
        from ncbot.modules.search.guided_mcts import TurnFeatures
        from ncbot.modules.networks.qnet import make_qnet
        from ncbot.pipelines.checkpoint import load_agent_checkpoint

        from ncbot.modules.networks.recurrent import require_feedforward

        config, data = load_agent_checkpoint(checkpoint)
        require_feedforward(config, "opponent 'agent:CHECKPOINT'")
        if config.env.game != game:
            raise ValueError(f"agent checkpoint {checkpoint!r} plays {config.env.game}, not {game}")
        self.qnet = make_qnet(data["n_features"], data["n_actions"], config.agent.hidden)
        self.qnet.load_state_dict(data["qnet"])
        self.qnet.eval()
        self.features = TurnFeatures(game, config.env.temporal, free_move, config.env.threats)
        self.features.check_reads(self.qnet)
        self.cells = self.features.cells
        self.rules = make_game(game, free_move)
        self.game, self.free_move = game, free_move
        self.generator = torch.Generator().manual_seed(seed)

    def select(self, boards, last_move, legal, player, generator=None, owners=None):
        import torch

        from ncbot.envs.opponents.lines import subgrid_owners

        rows = boards.shape[0]
        features = self.features.batch(boards, player, last_move)
        with torch.no_grad():
            q = self.qnet.module(features)[:, :self.cells]
        if self.rules.subgrids and owners is None:
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
        from ncbot.envs.rules import DRAWN, State

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
    from ncbot.envs.opponents import register_opponent

    def factory(arg, *, game, free_move, seed):
        if not arg:
            raise ValueError("opponent 'agent' needs a checkpoint path, e.g. 'agent:runs/default/checkpoint.pt'")
        return AgentOpponent(arg, game, free_move, seed)

    register_opponent("agent", factory, usage="agent:CHECKPOINT")
    register_qmcts_opponent()


# ------------------------------------------------------------------------------------ qmcts:N:CHECKPOINT
def guided_search(config, greedy, simulations: int, free_move: str | None = None, value: str | None = None):
    """A PUCT search whose priors (and values, unless a ``value`` network file is given) come from an already
    loaded agent's Q-network."""
    from ncbot.modules.networks.recurrent import require_feedforward
    from ncbot.modules.search.guided_mcts import policy_search

    require_feedforward(config, "the Q-guided search")
    return policy_search(greedy, config.env, simulations, free_move, value)


def load_guided_search(checkpoint: str, simulations: int, free_move: str | None = None):
    """(config, GuidedMCTS) of a saved agent: its Q-network gives the priors and values of a PUCT search."""
    config, greedy = load_agent(checkpoint)
    return config, guided_search(config, greedy, simulations, free_move)


def load_guided_agent(checkpoint: str, simulations: int, seed: int = 0, value: str | None = None):
    """(config, policy) for eval / ladder: the agent's greedy dialogue policy with game moves chosen by the search."""
    from ncbot.modules.search.guided_mcts import GuidedMCTSPolicy

    config, greedy = load_agent(checkpoint)
    return config, GuidedMCTSPolicy(greedy, guided_search(config, greedy, simulations, value=value), seed)


def register_qmcts_opponent() -> None:
    """Make ``qmcts:N:CHECKPOINT`` (MCTS guided by a trained agent's Q-network) a valid opponent name."""
    from ncbot.envs.opponents import register_opponent
    from ncbot.modules.search.guided_mcts import QMCTSOpponent, parse_qmcts

    def factory(arg, *, game, free_move, seed):
        simulations, checkpoint = parse_qmcts(arg)
        config, search = load_guided_search(checkpoint, simulations, free_move)
        if config.env.game != game:
            raise ValueError(f"qmcts checkpoint {checkpoint!r} plays {config.env.game}, not {game}")
        return QMCTSOpponent(search, game, free_move, seed)

    register_opponent("qmcts", factory, usage="qmcts:N:CHECKPOINT")
