"""The paper's ambiguous readings as one frozen object, built once (from a run's ``env`` section or ``make_env``'s
keywords) and handed to the parts that read it: the engine (``win_set``, ``about_to``), the env's believed board
(``taken_squares``, ``misread_rate``) and the dialogue model (``dialogues``, ``dialogue_subset``).

Why one object: a reading is one decision about what the paper's text means; passing it as one value keeps every
part that depends on it naming the same choice, and a new reading is one field here (docs/env.md "Readings").
Plain Python (no torch), so configs and tools can build and check it for free.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

# taken_squares: can the robot choose a square that is taken? Section 3: "all game moves were allowed from the
#   subset of those not taken yet (to the robot's knowledge)", yet the rewards price "a repeated (already taken)
#   action" at -5. never: only untaken squares are offered; refused: taken squares are offered too, refused at -5
#   with nothing changed; misread: the robot's knowledge of the board can be wrong (a misread user move), a square
#   really taken is refused at -5 and the refusal corrects the robot's knowledge; offered: misread, and every
#   square the robot knows is taken is offered too (the -5 payable to an agent without look-ahead masks).
TAKEN_SQUARES_CHOICES = ("never", "refused", "misread", "offered")
BELIEF_READINGS = ("misread", "offered")  # the readings that keep a believed board beside the true one
# win_set: what ``winning_actions`` (Algorithm 2's set A when non-empty) holds. wins_and_threats: every +5 move
#   (wins and "about to win" threats); wins: "action(s) leading to win (legally) the game", the moves that win now.
WIN_SET_CHOICES = ("wins_and_threats", "wins")
# about_to: when "+5 ... about to win" is paid. standing: on every move after which the robot has a winning
#   square; created: only on the move that creates it (the robot had no winning square before its move).
ABOUT_TO_CHOICES = ("standing", "created")
# dialogues: the example dialogues the act filter, the vocabulary and the simulated user are learnt from
#   (``ncbot.envs.dialogue.DIALOGUE_SETS``). compact: ours; paper: "your turn" before every user move.
DIALOGUE_CHOICES = ("compact", "paper")
FIELDS = ("taken_squares", "misread_rate", "win_set", "about_to", "dialogues", "dialogue_subset")


def check_choice(name: str, value: object, choices: tuple[str, ...]) -> str:
    """``value`` if it is one of ``choices``; one-line ValueError naming the option ``name`` and the choices."""
    if not isinstance(value, str) or value not in choices:
        raise ValueError(f"{name} must be one of {', '.join(choices)}; got {value!r}")
    return value


@dataclass(frozen=True)
class Readings:
    """One reading of each ambiguous passage of the paper; the defaults are this project's first readings.

    ``misread_rate``: the chance that the robot misreads a user move, required with ``taken_squares`` misread or offered
    and refused otherwise. ``dialogue_subset``: None (every example dialogue of the set) or (k, seed), the act filter
    and the simulated user learnt from a seeded subset of k dialogues (the data-budget curve)."""

    taken_squares: str = "never"
    misread_rate: float | None = None
    win_set: str = "wins_and_threats"
    about_to: str = "standing"
    dialogues: str = "compact"
    dialogue_subset: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        check_choice("taken_squares", self.taken_squares, TAKEN_SQUARES_CHOICES)
        object.__setattr__(self, "misread_rate", _misread_rate(self.taken_squares, self.misread_rate))
        check_choice("win_set", self.win_set, WIN_SET_CHOICES)
        check_choice("about_to", self.about_to, ABOUT_TO_CHOICES)
        check_choice("dialogues", self.dialogues, DIALOGUE_CHOICES)
        object.__setattr__(self, "dialogue_subset", _subset(self.dialogue_subset))

    @property
    def refused(self) -> bool:
        """Taken squares are offered too and refused at -5."""
        return self.taken_squares == "refused"

    @property
    def misread(self) -> bool:
        """The robot's knowledge of the board can be wrong (a believed board beside the true one): misread, offered."""
        return self.taken_squares in BELIEF_READINGS

    @property
    def offered(self) -> bool:
        """Misread, and the squares the robot knows are taken are offered too (refused at -5 with a re-read)."""
        return self.taken_squares == "offered"

    @classmethod
    def of(cls, readings: Readings | None = None, **fields: Any) -> Readings:
        """``readings`` with ``fields`` replaced (None: the defaults with ``fields``); unknown names are one line."""
        unknown = sorted(set(fields) - set(FIELDS))
        if unknown:
            raise ValueError(f"unknown reading {unknown[0]!r}; readings: {', '.join(FIELDS)}")
        base = {name: getattr(readings, name) for name in FIELDS} if readings is not None else {}
        return cls(**{**base, **fields})


def _misread_rate(taken_squares: str, misread_rate: Any) -> float | None:
    """A float in (0, 1), required with ``misread`` and ``offered`` and refused with the other readings."""
    if taken_squares not in BELIEF_READINGS:
        if misread_rate is not None:
            raise ValueError(f"misread_rate is only used with taken_squares=misread or offered (got taken_squares="
                             f"{taken_squares!r}, misread_rate={misread_rate!r}): leave it unset")
        return None
    if isinstance(misread_rate, bool) or not isinstance(misread_rate, (int, float)) or not 0.0 < misread_rate < 1.0:
        raise ValueError(f"misread_rate must be a number in (0, 1) with taken_squares={taken_squares}, got {misread_rate!r}")
    return float(misread_rate)


def _subset(subset: Any) -> tuple[int, int] | None:
    """None or (k, seed). The upper bound of k depends on the set and the game (``ncbot.envs.dialogue.subset_examples``)."""
    if subset is None:
        return None
    try:
        k, seed = subset
    except (TypeError, ValueError):
        raise ValueError(f"dialogue_subset must be None or (k, seed), two integers, got {subset!r}") from None
    if any(not isinstance(v, int) or isinstance(v, bool) for v in (k, seed)) or k < 1 or seed < 0:
        raise ValueError(f"dialogue_subset must be (k, seed) with an integer k >= 1 and seed >= 0, got {subset!r}")
    return int(k), int(seed)
