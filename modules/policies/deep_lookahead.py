"""k-step look-ahead (ablation axis ``lookahead``): A_hat grows to the moves after which the user can FORCE a win.

The paper's A_hat (Algorithm 2) holds the actions with a negative one-step reward: repeated moves and moves after
which the user wins at once (k = 1). Its future work asks for deeper look-ahead. Rule ``kN`` adds to A_hat every
robot move after which the user has a strategy that wins within N plies whatever the robot replies (plies counted
after the robot's move: user, robot, user, ...). Only the user's plies can win for the user, so k2 = k1 and
k4 = k3; k3 is the first rule that sees forks ("after this move the user makes two threats at once").

Why it needs more than the one-step keys: the search replays the game, so it reads the position from the env's
TensorDict: ``board`` (0 empty, 1 robot, 2 human), the robot's legal squares from ``action_mask`` (which fixes the
root's forced subgrid exactly), and, on Ultimate, who owns each subgrid. Owners depend on the order of play
(with ``free_move="anywhere"`` a subgrid can hold lines of both players); with temporal features the order is in
the observation (time[c] = move number / marks) and owners are exact; without them owners are read from the board
and the rare two-line subgrid is credited to the robot (as ``ncbot.envs.opponents.lines`` does).

The search runs on the opponents' bitboards (``ncbot.envs.opponents.bitboards``), one Python search per game that needs
it: games with at most one safe move skip it. Exactness is tested against a
brute-force search over ``ncbot.envs.rules`` (tests/modules/test_deep_lookahead.py); cost per decision: bench/studies/lookahead_cost.py.

Rule names: ``k1`` .. ``k5`` assume the paper's ``free_move="anywhere"``; ``k1_open`` .. ``k5_open`` the
``open_subgrids`` variant. A rule that meets a root mask contradicting its variant raises ValueError.
"""
from __future__ import annotations

import torch
from tensordict import TensorDictBase

from ncbot.envs.opponents.bitboards import FREE_SQUARES, IS_LINE, ONGOING, StandardBits, UltimateBits
from ncbot.envs.rules import LINES_3X3, SUBGRID_CELLS, SUBGRID_OF_CELL
from ncbot.modules.policies.mask_rules import AVAILABLE_KEY, LOOKAHEAD_REWARD_KEY, WINNING_KEY, fallback, nonempty_or

ROBOT, HUMAN = 1, 2
MAX_PLIES = 5
TEMPORAL_FEATURES = {9: 73, 81: 289}  # observation width with the temporal features (their last `cells` columns)

# --------------------------------------------------------------------------------------------- search on bitboards


def win_in_one(engine, pos: tuple) -> bool:
    """True if the side to move has a legal move that wins the game at once (3x3 and Ultimate bitboards: table
    look-ups only; any other game's search positions: each move played)."""
    if not isinstance(engine, (StandardBits, UltimateBits)):
        turn = engine.turn(pos)
        return engine.result(pos) == ONGOING and any(engine.result(engine.play(pos, m)) == turn for m in engine.moves(pos))
    if isinstance(engine, StandardBits):
        bits0, bits1, turn, result = pos
        if result != ONGOING:
            return False
        own = bits0 if turn == 0 else bits1
        return any(IS_LINE[own | 1 << p] for p in FREE_SQUARES[bits0 | bits1])
    subs0, subs1, decided, macro0, macro1, target, turn, _, result = pos
    if result != ONGOING:
        return False
    own, macro = (subs0, macro0) if turn == 0 else (subs1, macro1)
    # only a move that takes an open subgrid completing a line of subgrids wins; a free move may go anywhere
    for k in ((target,) if target >= 0 else range(9)):
        if decided >> k & 1 or not IS_LINE[macro | 1 << k]:
            continue
        if any(IS_LINE[own[k] | 1 << p] for p in FREE_SQUARES[subs0[k] | subs1[k]]):
            return True
    return False


def forces_win(engine: StandardBits | UltimateBits, pos: tuple, plies: int) -> bool:
    """True if the side to move in ``pos`` can force a win within ``plies`` plies (its own moves included)."""
    if plies < 1 or engine.result(pos) != ONGOING:
        return False
    if win_in_one(engine, pos):
        return True
    if plies < 3:
        return False
    for move in engine.moves(pos):
        child = engine.play(pos, move)
        if engine.result(child) != ONGOING:  # not a win (checked above): a draw ends the attack
            continue
        if all(_reply_still_loses(engine, child, reply, plies - 2) for reply in engine.moves(child)):
            return True
    return False


def _reply_still_loses(engine, child: tuple, reply: int, plies: int) -> bool:
    after = engine.play(child, reply)
    return engine.result(after) == ONGOING and forces_win(engine, after, plies)


def losing_moves(engine: StandardBits | UltimateBits, pos: tuple, candidates: list[int], plies: int) -> list[int]:
    """The candidate moves of the side to move after which the other side forces a win within ``plies`` plies."""
    losing = []
    for move in candidates:
        after = engine.play(pos, move)
        if engine.result(after) == ONGOING and forces_win(engine, after, plies):
            losing.append(move)
    return losing


# --------------------------------------------------------------------------------------------- positions from the TD


def owners_from_order(board: list[int], order: list[int]) -> list[int]:
    """Ultimate subgrid owners (0 open, 1, 2, 3 drawn) from the board and each cell's move number (0 empty).

    The owner is whoever completed a line first: a line's completion time is its latest move number.
    """
    owners = []
    for cells in SUBGRID_CELLS:
        marks = [board[c] for c in cells]
        first = {}
        for line in LINES_3X3:
            code = marks[line[0]]
            if code and marks[line[1]] == code and marks[line[2]] == code:
                done = max(order[cells[i]] for i in line)
                first[code] = min(first.get(code, done), done)
        if first:
            owners.append(min(first, key=first.get))
        else:
            owners.append(3 if all(marks) else 0)
    return owners


def move_order(observation: torch.Tensor, boards: torch.Tensor) -> torch.Tensor | None:
    """(B, cells) move numbers from the temporal features, or None when the observation has none."""
    cells = boards.shape[-1]
    if observation is None or observation.shape[-1] != TEMPORAL_FEATURES[cells]:
        return None
    n_marks = (boards != 0).sum(-1, keepdim=True)
    return (observation[:, -cells:] * n_marks).round().long() * (boards != 0)


# --------------------------------------------------------------------------------------------- the mask rule


class KStepLookahead:
    """Mask rule ``kN``: the paper's Algorithm 2 with A_hat extended by an exact N-ply forced-loss search.

    ``explore_mask`` is the paper's set A (as in ``one_step``); ``greedy_mask`` is A minus the one-step A_hat minus
    the moves that lose by force within N plies. The env's A also holds "about to win" moves (making a threat earns
    +5), and a threat can lead into a forced loss; when every move of A does, the greedy mask takes the other
    available moves that survive the search, then falls back to the one-step mask (the robot at least avoids
    immediate losses) and to A.
    """

    needs_tensordict = True

    def __init__(self, plies: int, free_move: str = "anywhere") -> None:
        if not 1 <= int(plies) <= MAX_PLIES:
            raise ValueError(f"k-step look-ahead needs 1 <= k <= {MAX_PLIES} plies, got {plies}")
        if free_move not in ("anywhere", "open_subgrids"):
            raise ValueError(f"free_move must be anywhere or open_subgrids, got {free_move!r}")
        self.plies, self.free_move = int(plies), free_move
        self.engines = {9: StandardBits(), 81: UltimateBits(free_move)}

    def __call__(self, available: torch.Tensor, reward: torch.Tensor, winning: torch.Tensor):
        raise ValueError(f"look-ahead k{self.plies} reads the board: use it through modules.policies.masks.LookaheadMasks "
                         "(or masks_from_tensordict), not as a three-tensor rule")

    def masks_from_tensordict(self, td: TensorDictBase, untaken: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """(explore, greedy); ``untaken`` (``all_negative="untaken"``): the last fallback, when no move is safe even
        one step deep, is set A without the squares taken to the robot's knowledge, as the one-step rules do."""
        available, reward, winning = td.get(AVAILABLE_KEY), td.get(LOOKAHEAD_REWARD_KEY), td.get(WINNING_KEY)
        set_a = nonempty_or(winning & available, available)
        safe_now = available & ~(reward < 0)  # available minus the one-step A_hat
        deep = self.forced_losses(td, safe_now)
        # The env's set A holds "about to win" moves (a threat earns +5), and a threat can walk into a forced
        # loss: then the greedy choice may leave A for a move that survives the deeper search.
        greedy = nonempty_or(set_a & safe_now & ~deep, safe_now & ~deep)
        return set_a, nonempty_or(greedy, nonempty_or(set_a & safe_now, fallback(set_a, untaken)))

    def forced_losses(self, td: TensorDictBase, candidates: torch.Tensor) -> torch.Tensor:
        """(B, A) bool: candidate game moves after which the user forces a win within k plies."""
        boards = td.get("board")
        batch_shape = boards.shape[:-1]
        boards = boards.reshape(-1, boards.shape[-1])
        candidates = candidates.reshape(-1, candidates.shape[-1])
        cells = boards.shape[-1]
        out = torch.zeros_like(candidates)
        if self.plies < 3 or cells not in self.engines:  # k1/k2: the env's one-step reward already says it all
            return out.reshape(*batch_shape, -1)
        moves = candidates[:, :cells]
        rows = (moves.sum(-1) >= 2).nonzero()  # one candidate: nothing to choose
        if rows.numel() == 0:
            return out.reshape(*batch_shape, -1)
        order = move_order(td.get("observation", None), boards) if cells == 81 else None
        legal = td.get(AVAILABLE_KEY).reshape(moves.shape[0], -1)[:, :cells]
        engine = self.engines[cells]
        board_rows = boards.tolist()
        for row in rows.flatten().tolist():
            board = board_rows[row]
            owners = None
            if cells == 81:
                owners = owners_from_order(board, order[row].tolist()) if order is not None else None
                self._check_variant(board, owners, legal[row])
            pos = engine.from_board(board, ROBOT, -1, owners)
            choices = moves[row].nonzero().flatten().tolist()
            for move in losing_moves(engine, pos, choices, self.plies):
                out[row, move] = True
        return out.reshape(*batch_shape, -1)

    def _check_variant(self, board: list[int], owners: list[int] | None, legal: torch.Tensor) -> None:
        """Refuse a rule whose free-move variant contradicts the env (visible when the root move is free)."""
        legal_cells = legal.nonzero().flatten().tolist()
        if not legal_cells:
            return
        subgrid_of = [SUBGRID_OF_CELL[c] for c in legal_cells]
        if len(set(subgrid_of)) == 1:
            return  # a forced (or one-subgrid) move says nothing about the variant
        if owners is None:
            owners = [_owner_from_board(board, k) for k in range(9)]
        in_decided = any(owners[k] != 0 for k in subgrid_of)
        if self.free_move == "open_subgrids" and in_decided:
            raise ValueError("look-ahead kN_open (free_move=open_subgrids) met an env that lets the robot play in "
                             "decided subgrids: use kN for free_move=anywhere")
        empty_in_decided = any(owners[SUBGRID_OF_CELL[c]] != 0 for c in range(81) if board[c] == 0)
        if self.free_move == "anywhere" and not in_decided and empty_in_decided:
            raise ValueError("look-ahead kN (free_move=anywhere) met an env that forbids decided subgrids on a free "
                             "move: use kN_open for free_move=open_subgrids")


def _owner_from_board(board: list[int], k: int) -> int:
    marks = [board[c] for c in SUBGRID_CELLS[k]]
    for code in (ROBOT, HUMAN):
        if any(all(marks[i] == code for i in line) for line in LINES_3X3):
            return code
    return 3 if all(marks) else 0
