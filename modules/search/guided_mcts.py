"""MCTS guided by the learnt Q-network: the paper's future work ("MinMax/MCTS combined with the learnt policy").

The shared search loop of ``ncbot.envs.opponents.search`` with PUCT (AlphaZero-style) selection and a Q-guided
evaluator, on the opponents' bitboards, with three inputs from the agent:
- priors: softmax(Q / temperature) over the legal cells of the side to move, read from the Q-network on the
  features of a typical game turn seen from that side (``TurnFeatures``);
- values: a leaf is scored by ``value_weight * v_Q + (1 - value_weight) * random playout``, where
  v_Q = (clip(max Q, -5, 5) / 5 + 1) / 2 maps the paper's reward scale (+5 win / -5 loss) to [0, 1]; or, given a
  ``value_net`` (Ultimate, ``ncbot.modules.search.value_net``), by that network alone (no playout);
- the root keeps the paper's one-step masks: a winning cell is taken at once, and cells after which the other
  side wins at once are searched only when every cell is such (Algorithm 2's A and A_hat).

``simulations`` is the budget per decision. All chance comes from one seed per decision drawn from the caller's
torch generator, so results are reproducible by seed. Two front-ends: ``QMCTSOpponent`` (an ``ncbot.envs.opponents``
opponent, name ``qmcts:N:CHECKPOINT`` registered by ``ncbot.pipelines.evaluate.ladder``) and ``GuidedMCTSPolicy`` (the robot's
policy at eval time: the greedy dialogue policy, with its game moves chosen by the search).
"""
from __future__ import annotations

import math
import random
import time
from typing import Any

import numpy as np
import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase
from torch import nn

from ncbot.envs.core import HUMAN, ROBOT
from ncbot.envs.opponents.base import Opponent
from ncbot.envs.games import make_game
from ncbot.envs.opponents.bitboards import ONGOING
from ncbot.envs.opponents.search import PUCT, Node, RandomRollout, result_value, run_search, visits_by_move
from ncbot.modules.policies.deep_lookahead import move_order, owners_from_order, win_in_one
from ncbot.modules.policies.mask_rules import AVAILABLE_KEY, GREEDY_MASK_KEY
from ncbot.modules.networks.qnet import ACTION_VALUE_KEY, MLPReader
from ncbot.modules.search.value_net import VALUE_GAME, ValueNetEvaluator

ROOT_KEYS = (GREEDY_MASK_KEY, AVAILABLE_KEY)  # what the robot's root is searched over (GuidedMCTSPolicy)

DEFAULT_C_PUCT = 1.5
DEFAULT_TEMPERATURE = 2.0  # Q-values span about +-5 (the paper's rewards): a softer softmax keeps the search broad
DEFAULT_VALUE_WEIGHT = 0.25  # v_Q is a shaped-reward estimate, not a win rate: playouts stay the main signal


class TurnFeatures:
    """Paper features of a typical game turn for arbitrary boards, as the agent saw them while playing.

    Own marks as robot moves, the other side's as human moves, the words of "I take this one" and the user's
    move utterance, no command, and (temporal) the last mark at 1.0 and the others at 0.5 (a tree node knows its
    last move but not the order of the earlier ones). Same reading as ``ncbot.pipelines.agents.AgentOpponent``.
    ``threats``: the env's ``threat_features`` planes too, seen from the side to move; Ultimate subgrid owners are
    read from the board (exact under ``open_subgrids``; under ``anywhere`` a subgrid holding lines of both sides
    counts as the robot's, as in ``ncbot.envs.opponents.lines.subgrid_owners``).
    """

    def __init__(self, game: str, temporal: bool, free_move: str = "anywhere", threats: bool = False) -> None:
        from ncbot.envs import make_env
        from ncbot.envs.dialogue import MOVE, USER_ACTS

        env = make_env(game, batch_size=(1,), temporal=temporal, free_move=free_move, seed=0, threat_features=threats)
        names, model = env.feature_names, env.model
        self.cells, self.n_features = env.cells, env.n_features
        self.robot_plane = 0
        self.human_plane = self.cells
        first_cell = "0" * len(str(self.cells - 1))  # the feature names' zero-padded first cell: [0] or [00]
        self.time_plane = names.index(f"time[{first_cell}]") if temporal else None
        self.threat_plane = names.index(f"robot_threat[{first_cell}]") if threats else None  # planes run to the end
        self.rules = make_game(game, free_move)
        self.engine = self.rules.search_engine()  # reads the threats of a position given as cell lists
        if threats and not hasattr(self.engine, "threat_indices"):
            raise ValueError(f"the search reads threat planes of positions; game {self.rules.name!r} gives none")
        base = torch.zeros(self.n_features)
        word_start = names.index(f"word[{model.words[0]}]")
        move_utterance = min((u for u, a in enumerate(model.utterance_acts.tolist()) if a == USER_ACTS.index("GameMove")),
                             key=lambda u: len(model.utterance_texts[u]))
        base[word_start:word_start + len(model.words)] = torch.maximum(model.template_words[1 + MOVE],
                                                                       model.utterance_words[move_utterance])
        self.base = base.numpy()  # float32; one position's features start from a numpy copy (``__call__``)
        env.close()

    def check_reads(self, qnet: nn.Module) -> None:
        """A clear error when ``qnet`` reads other features than these (built for another env: other game,
        temporal features or threat planes) instead of a shape error deep inside a search."""
        first = next((m for m in qnet.modules() if isinstance(m, nn.Linear)), None)
        if first is not None and first.in_features != self.n_features:
            raise ValueError(f"this agent's Q-network reads {first.in_features} features, a typical game turn of "
                             f"this env has {self.n_features} (features built for another env configuration)")

    def __call__(self, own: list[int], other: list[int], last_move: int, pos: tuple | None = None) -> np.ndarray:
        """(F,) float32 features for one position: ``own``/``other`` are the cells of the side to move / the other
        side; ``pos`` the same position as a bitboard when the caller has it (the threat planes are read from it).
        numpy, not torch: this runs once per search expansion, where torch's per-op cost dominates."""
        features = self.base.copy()
        ones = [self.robot_plane + c for c in own] + [self.human_plane + c for c in other]
        if self.time_plane is not None:
            features[[self.time_plane + c for c in own + other]] = 0.5
            if last_move >= 0:
                ones.append(self.time_plane + last_move)
        features[ones] = 1.0
        if self.threat_plane is not None:
            if pos is None:
                board = [0] * self.cells
                for cell in own:
                    board[cell] = ROBOT
                for cell in other:
                    board[cell] = HUMAN
                pos = self.engine.from_board(board, ROBOT)
            features[[self.threat_plane + i for i in self.engine.threat_indices(pos)]] = 1.0
        return features

    def batch(self, boards: torch.Tensor, player: int, last_move: torch.Tensor) -> torch.Tensor:
        """(B, F) features of (B, cells) boards (codes 1/2) seen from ``player``; ``last_move`` (B,), -1 none."""
        features = torch.from_numpy(self.base).repeat(boards.shape[0], 1)
        features[:, self.robot_plane:self.robot_plane + self.cells] = (boards == player).float()
        features[:, self.human_plane:self.human_plane + self.cells] = ((boards != 0) & (boards != player)).float()
        if self.time_plane is not None:
            times = (boards != 0).float() * 0.5
            has_last = (last_move >= 0).nonzero().flatten()
            times[has_last, last_move[has_last]] = 1.0
            features[:, self.time_plane:self.time_plane + self.cells] = times
        if self.threat_plane is not None:  # the side to move as the robot (code 1), the other as the human
            seen = torch.where(boards == player, ROBOT, torch.where(boards != 0, HUMAN, 0)).to(torch.int8)
            features[:, self.threat_plane:] = self.rules.threat_planes(seen)
        return features


class QGuidedEvaluator:
    """The search's evaluator: expands a leaf with softmax(Q / temperature) priors and scores it by
    ``value_weight * v_Q + (1 - value_weight) * random playout`` (a finished game: its result)."""

    def __init__(self, search: "GuidedMCTS") -> None:
        self.search = search
        self.rollout = RandomRollout(search.engine)

    def evaluate(self, node: Node, rand) -> float:
        search, engine = self.search, self.search.engine
        result = engine.result(node.pos)
        if result != ONGOING:
            return result_value(result, node.mover)
        v_q = search.expand(node, engine.moves(node.pos)) if node.moves is None else 0.5
        weight = search.value_weight
        return weight * (1.0 - v_q) + (1.0 - weight) * self.rollout.evaluate(node, rand)


class GuidedMCTS:
    """PUCT search whose priors and leaf values come from a Q-network (see the module docstring).

    The loop is ``ncbot.envs.opponents.search.run_search`` with ``PUCT`` selection and ``QGuidedEvaluator`` (or
    ``ValueNetEvaluator`` when a ``value_net`` is given)."""

    def __init__(self, qnet: nn.Module, features: TurnFeatures, game: str, free_move: str = "anywhere",
                 simulations: int = 100, c_puct: float = DEFAULT_C_PUCT, temperature: float = DEFAULT_TEMPERATURE,
                 value_weight: float = DEFAULT_VALUE_WEIGHT, value_net: nn.Module | None = None) -> None:
        if simulations < 1:
            raise ValueError(f"guided MCTS needs at least 1 simulation, got {simulations}")
        if not 0.0 <= value_weight <= 1.0:
            raise ValueError(f"value_weight must be in [0, 1], got {value_weight}")
        if temperature <= 0:
            raise ValueError(f"temperature must be > 0, got {temperature}")
        features.check_reads(qnet)
        self.qnet, self.features = qnet, features
        self._reader = MLPReader.of(qnet)
        rules = make_game(game, free_move)
        self.engine = rules.search_engine()
        self.cells, self.subgrids = rules.n_cells, rules.subgrids  # subgrid owners: read from the move order
        self.simulations, self.c_puct = int(simulations), float(c_puct)
        self.temperature, self.value_weight = float(temperature), float(value_weight)
        # after a search: each visited root move's mean value in [0, 1] for the side to move ({} when the root
        # rules decided without searching); the search teacher reads it (modules/search/search_targets.py)
        self.root_values: dict[int, float] = {}
        if value_net is not None and rules.id != VALUE_GAME:
            raise ValueError(f"value networks score Ultimate positions; this agent plays {game} "
                             "(--value needs an Ultimate agent)")
        if value_net is None:  # the Q-guided leaf value needs the Q read of the expansion: expand at the leaf
            self.policy, self.evaluator = PUCT(self.engine, self.c_puct), QGuidedEvaluator(self)
        else:
            self.policy = PUCT(self.engine, self.c_puct, expand=self.expand_visited)
            self.evaluator = ValueNetEvaluator(self, value_net)

    def refresh(self) -> None:
        """Copy the Q-network's current weights into the numpy reader (a search during training, after updates)."""
        self._reader = MLPReader.of(self.qnet)

    # -- Q-network reads --------------------------------------------------------------------------------------
    def _cells_of(self, pos: tuple) -> tuple[list[int], list[int]]:
        """(cells of the side to move, cells of the other side) of a search position."""
        return self.engine.position_cells(pos)

    def _q(self, pos: tuple, last_move: int, moves: list[int]) -> list[float]:
        own, other = self._cells_of(pos)
        x = self.features(own, other, last_move, pos)
        if self._reader is not None:
            return self._reader(x)[moves].tolist()
        with torch.no_grad():
            from ncbot.modules.device import module_device

            return self.qnet(torch.from_numpy(x).unsqueeze(0).to(module_device(self.qnet)))[0][moves].tolist()

    def expand(self, node: Node, moves: list[int], q: list[float] | None = None) -> float:
        """Set the node's moves and priors; the Q-value estimate v_Q in [0, 1] for the side to move.

        ``q``: the moves' Q-values when the caller already has them (the root, read from the real observation);
        else they are read on ``TurnFeatures``."""
        if q is None:
            q = self._q(node.pos, node.move, moves)
        top = max(q)
        weights = [math.exp((v - top) / self.temperature) for v in q]
        total = sum(weights)
        node.moves, node.priors = moves, [w / total for w in weights]
        return (max(-5.0, min(5.0, top)) / 5.0 + 1.0) / 2.0

    def expand_visited(self, node: Node) -> bool:
        """``PUCT``'s lazy expansion (value-network search): expand a node already scored once; False if its game
        is over."""
        if self.engine.result(node.pos) != ONGOING:
            return False
        self.expand(node, self.engine.moves(node.pos))
        return True

    # -- the search --------------------------------------------------------------------------------------------
    def search(self, pos: tuple, root_moves: list[int], rng: random.Random,
               root_q: dict[int, float] | None = None) -> tuple[int, dict[int, int]]:
        """The chosen root move and the visit count of every searched root move.

        ``root_q`` (move -> Q-value), if given, sets the root's priors instead of a read on ``TurnFeatures``: the
        robot's policy passes the Q-values of the real observation (its words, exact move order), which the
        typical-turn features only approximate."""
        engine = self.engine
        turn = engine.turn(pos)
        self.root_values = {}
        for move in root_moves:  # A: a winning cell is taken at once
            if engine.result(engine.play(pos, move)) == turn:
                return move, {move: 0}
        safe = [m for m in root_moves if not win_in_one(engine, engine.play(pos, m))]  # A_hat: immediate losses
        moves = safe or list(root_moves)
        if len(moves) == 1:
            return moves[0], {moves[0]: 0}
        root = Node(pos, -1, -1)
        self.expand(root, moves, None if root_q is None else [root_q[m] for m in moves])
        rand = rng.random
        run_search(root, self.simulations, rand, self.policy, self.evaluator)
        self.root_values = {child.move: child.value / child.visits for child in root.children
                            if child is not None and child.visits}
        return self.policy.choose(root, rand), visits_by_move(root)


class QMCTSOpponent(Opponent):
    """``qmcts:N:CHECKPOINT``: the Q-guided search as a move chooser for batches of boards (env user, arena)."""

    def __init__(self, search: GuidedMCTS, game: str, free_move: str, seed: int = 0) -> None:
        super().__init__(game, free_move, seed)
        self.search = search
        self.name = f"qmcts:{search.simulations}"

    def _select(self, boards, last_move, legal, player, generator, owners):
        cells = torch.zeros(boards.shape[0], dtype=torch.long)
        seeds = torch.randint(0, 2**62, (boards.shape[0],), generator=generator).tolist()
        board_rows, last_moves, legal_rows = boards.tolist(), last_move.tolist(), legal.tolist()
        owner_rows = owners.tolist() if owners is not None else [None] * boards.shape[0]
        for row in torch.nonzero(legal.any(dim=1)).flatten().tolist():
            root_moves = [c for c, ok in enumerate(legal_rows[row]) if ok]
            pos = self.search.engine.from_board(board_rows[row], player, last_moves[row], owner_rows[row])
            cells[row], _ = self.search.search(pos, root_moves, random.Random(seeds[row]))
        return cells


class GuidedMCTSPolicy(TensorDictModuleBase):
    """The robot's eval-time policy: the greedy dialogue policy, with every game move chosen by ``GuidedMCTS``.

    Dialogue acts stay the greedy policy's; on rows where ``action_mask`` allows game moves the search replaces
    the action. The root is searched over the moves of ``root_key``: by default the agent's own ``greedy_mask``
    (its look-ahead masks, as in greedy play: the search only reorders what the greedy policy could choose),
    or ``action_mask`` (every legal move; the search's own root masks then keep wins and skip immediate losses).
    The root's priors are the Q-values of the real observation (``action_value``, computed by the greedy
    chain). Ultimate owners come from the temporal features when the observation has them (exact), else from
    the board.

    ``searching`` ((B,) bool or None): rows whose game move is searched; the others keep the greedy move.
    ``ncbot.pipelines.evaluate.games.play_games`` sets it to the games still being counted, so no search is spent on the
    extra games of slots that already finished. ``decisions`` / ``cpu_seconds`` count the searched moves and
    their process CPU time (the cost per robot move that eval reports).
    """

    in_keys = ["observation", "action_mask", "board"]
    out_keys = ["action"]

    def __init__(self, greedy: nn.Module, search: GuidedMCTS, seed: int = 0, prune=None,
                 root_key: str = GREEDY_MASK_KEY) -> None:
        """``prune``: an optional k-step rule (``ncbot.modules.policies.deep_lookahead.KStepLookahead``); the root then skips the
        moves it proves lost by force, so the simulations are spent on moves that can still be saved."""
        super().__init__()
        if root_key not in ROOT_KEYS:
            raise ValueError(f"root_key must be one of {', '.join(ROOT_KEYS)}, got {root_key!r}")
        self.greedy, self.search, self.prune, self.root_key = greedy, search, prune, root_key
        self.generator = torch.Generator().manual_seed(int(seed))
        self.searching: torch.Tensor | None = None
        self.decisions, self.cpu_seconds = 0, 0.0
        self.root_values: dict[int, dict[int, float]] = {}  # row -> the search's root values, of the last call

    policy_device = "cpu"  # reads and writes CPU TensorDicts; its greedy network runs where it lives

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        from ncbot.modules.device import on_device

        tensordict = on_device(self.greedy)(tensordict)
        cells = self.search.cells
        legal = tensordict.get(AVAILABLE_KEY)[:, :cells]
        playing = legal.any(-1)
        if self.searching is not None:
            playing = playing & self.searching
        rows = playing.nonzero().flatten().tolist()
        self.root_values = {}
        if not rows:
            return tensordict
        started = time.process_time()
        moves = tensordict.get(self.root_key)[:, :cells] & legal
        moves = torch.where(moves.any(-1, keepdim=True), moves, legal)
        boards = tensordict.get("board")
        order = move_order(tensordict.get("observation"), boards) if self.search.subgrids else None
        q_rows = tensordict.get(ACTION_VALUE_KEY)[:, :cells].tolist()
        action = tensordict.get("action").clone()
        seeds = torch.randint(0, 2**62, (len(rows),), generator=self.generator).tolist()
        board_rows = boards.tolist()
        if self.prune is not None:
            lost = self.prune.forced_losses(tensordict, tensordict.get(AVAILABLE_KEY))[:, :cells]
            survivors = moves & ~lost
            moves = torch.where(survivors.any(-1, keepdim=True), survivors, moves)
        for row, seed in zip(rows, seeds):
            owners = owners_from_order(board_rows[row], order[row].tolist()) if order is not None else None
            pos = self.search.engine.from_board(board_rows[row], 1, -1, owners)
            root_moves = moves[row].nonzero().flatten().tolist()
            root_q = {m: q_rows[row][m] for m in root_moves}
            action[row], _ = self.search.search(pos, root_moves, random.Random(seed), root_q)
            self.root_values[row] = self.search.root_values
        tensordict.set("action", action)
        self.decisions += len(rows)
        self.cpu_seconds += time.process_time() - started
        return tensordict


def parse_qmcts(arg: str | None) -> tuple[int, str]:
    """``"N:CHECKPOINT"`` (the part after ``qmcts:``) -> (simulations, checkpoint path); ValueError otherwise."""
    budget, _, checkpoint = (arg or "").partition(":")
    try:
        simulations = int(budget)
    except ValueError:
        simulations = 0
    if simulations < 1 or not checkpoint:
        raise ValueError(f"opponent 'qmcts' needs a simulation budget and a checkpoint, e.g. "
                         f"'qmcts:100:runs/default/checkpoint.pt'; got 'qmcts:{arg or ''}'")
    return simulations, checkpoint


def policy_search(greedy: nn.Module, env: Any, simulations: int, free_move: str | None = None,
                  value: str | None = None) -> GuidedMCTS:
    """A PUCT search whose priors (and values, unless a ``value`` network file is given) come from an agent's greedy
    policy (its chain starts with the Q-network, ``ncbot.modules.policies.policy.make_policies``); ``env`` is the
    agent's env config section (game, temporal, free_move, threats)."""
    free_move = free_move or env.free_move
    value_net = None
    if value is not None:  # GuidedMCTS refuses a value network on a 3x3 agent
        from ncbot.modules.search.value_net import load_value_net

        value_net = load_value_net(value, free_move)
    features = TurnFeatures(env.game, env.temporal, free_move, env.threats)
    return GuidedMCTS(greedy[0].module, features, env.game, free_move, simulations, value_net=value_net)
