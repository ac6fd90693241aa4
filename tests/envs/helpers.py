"""Helpers the env tests share."""
from __future__ import annotations


def to_robot_move(env, td):
    """Step game 0 through the dialogue (the first allowed non-move act each time) until the robot may move."""
    for _ in range(20):
        if bool(td["action_mask"][0, : env.cells].any()):
            return td
        td["action"] = td["action_mask"][0].nonzero()[0]
        td = env.step(td)["next"]
    raise AssertionError("the robot never got a move")


def engine_of(game: str, free_move: str = "anywhere", **readings):
    """The batched engine of ``game`` under the given readings (``Game.engine``)."""
    from ncbot.envs.games import make_game
    from ncbot.envs.readings import Readings

    return make_game(game, free_move).engine(Readings(**readings))


def search_of(game: str, free_move: str = "anywhere"):
    """The search positions of ``game`` (``Game.search_engine``)."""
    from ncbot.envs.games import make_game

    return make_game(game, free_move).search_engine()


class QueuedMoves:
    """An env opponent whose moves the test queues before stepping (``queue(cells)``, one per game of the batch);
    ``select`` takes ``rows`` (the games that move), as opponents holding per-game input do. A missing or illegal
    queued move raises ValueError."""

    name = "queued"

    def __init__(self) -> None:
        from collections import deque

        self._pending = deque()

    def queue(self, cells) -> None:
        import torch

        self._pending.append(torch.as_tensor(cells, dtype=torch.int64).reshape(-1))

    def select(self, boards, last_move, legal, player, generator=None, rows=None):
        if not self._pending:
            raise ValueError("no queued move: call queue(cells) before stepping the env")
        cells = self._pending.popleft()
        if rows is not None:
            cells = cells[rows]
        if cells.shape[0] != legal.shape[0]:
            raise ValueError(f"queued move holds {cells.shape[0]} cells, but {legal.shape[0]} games move now")
        ok = (cells >= 0) & (cells < legal.shape[1])
        if not bool(ok.all()) or not bool(legal.gather(1, cells.unsqueeze(1)).all()):
            raise ValueError(f"queued user move {cells.tolist()} is not legal here")
        return cells
