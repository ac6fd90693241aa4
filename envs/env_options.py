"""The dialogue env's options, checked: one clear ValueError per bad value, before anything is built."""
from __future__ import annotations

import inspect
from typing import Any

from ncbot.envs.core import FIRST_CHOICES
from ncbot.envs.readings import FIELDS as READING_NAMES

# make_env's options: the env's own, then the paper's readings, by keyword or as one ``readings`` object
# (``ncbot.envs.readings``, docs/env.md "Readings")
ENV_OPTIONS = ("first", "opponent", "asr_confidence", "max_actions", "hearing", "threat_features", "readings")
OPTION_NAMES = ENV_OPTIONS + READING_NAMES


def resolve_opponent(opponent: Any, game: str, free_move: str, seed: int) -> tuple[Any, set[str]]:
    """None for the inline uniform-random user; else an object with ``select`` (by name or given).

    Also returns which optional keywords its ``select`` takes: ``owners`` (subgrid owners of a game that tracks them)
    and ``rows`` (the batch indices of the games that move, for opponents that hold per-game input, such as moves a
    caller queued from outside).
    """
    if isinstance(opponent, str):
        if opponent == "random":
            return None, set()
        from ncbot.envs.opponents import make_opponent, opponent_choices

        try:
            opponent = make_opponent(opponent, game=game, free_move=free_move, seed=seed)
        except (KeyError, ValueError) as error:
            reason = str(error.args[0] if error.args else error)
            if "choose one of" in reason:  # an unknown name: the message lists the choices already
                raise ValueError(reason) from None
            raise ValueError(f"opponent {opponent!r} is invalid ({reason}); choices: {', '.join(opponent_choices())}") from None
    if not callable(getattr(opponent, "select", None)):
        raise ValueError(f"opponent must be a name (e.g. 'random') or an object with a select(...) method, got {opponent!r}")
    params = set(inspect.signature(opponent.select).parameters) & {"owners", "rows"}
    return opponent, params


def first_of(first: str) -> str:
    """The ``first`` option (who opens the game), checked."""
    if first not in FIRST_CHOICES:
        raise ValueError(f"first must be one of {', '.join(FIRST_CHOICES)}; got {first!r}")
    return first


def check_batch(batch_size: Any) -> int:
    if isinstance(batch_size, int):
        batch_size = (batch_size,)
    try:
        dims = tuple(int(b) for b in batch_size)
    except TypeError:
        raise ValueError(f"batch_size must be an int or a 1-tuple like (64,), got {batch_size!r}") from None
    if len(dims) != 1 or dims[0] < 1:
        raise ValueError(f"batch_size must be a 1-tuple with a positive size like (64,), got {batch_size!r}")
    return dims[0]


def check_confidence(bounds: Any) -> tuple[float, float]:
    try:
        low, high = (float(v) for v in bounds)
    except (TypeError, ValueError):
        raise ValueError(f"asr_confidence must be (low, high) of a uniform distribution in [0, 1], got {bounds!r}") from None
    if not 0.0 <= low <= high <= 1.0:
        raise ValueError(f"asr_confidence must satisfy 0 <= low <= high <= 1, got {bounds!r}")
    return low, high


def check_hearing(hearing: Any) -> Any:
    """None (uniform ASR confidences) or an object with ``hear(utterances (B,), generator)`` (``ncbot.speech.hearing``)."""
    if hearing is not None and not callable(getattr(hearing, "hear", None)):
        raise ValueError(f"hearing must be None or an object with a hear(utterances, generator) method, got {hearing!r}")
    return hearing
