"""The person's spoken answer to "where did you draw?": a small fixed phrase per cell, the ears that hear it, and
the words mapped back to a cell.

Why more recognisers: a field system listens for what it just asked. The dialogue's LM (speech.asr, built from
the example dialogues) has no cell words, so the question "where did you draw?" gets its own small LM (the
game's cell phrases) and the question "did you say top left?" another (its two answers, `CONFIRM_YES` and
`CONFIRM_NO`). The dialogue recogniser is never fed these answers, so they never change how a dialogue reply is heard.
Why whole sentences to confirm: a lone "yes" or "no" is too short to hear in noise (`python bench/studies/cell_answers.py
--lone-words`, the four play voices, 32 confirmations per level: lone words through the cell phrases' LM 10 and 15
swapped at white 10 / 5 dB; "yes, that is right" / "no, that is wrong" through their own LM 0 and 6, 1 at babble
10 dB).
An answer counts as "yes" if it holds "yes" or "right" and neither "no" nor "wrong", "no" the other way round,
and as nothing otherwise.

Phrases: 3x3 cells are "top left", "top middle", ..., "centre", ..., "bottom right" (row then column; the middle
cell is "centre", so a dropped "left" of "middle left" is no phrase rather than another cell). Ultimate cells
name the small square, then the cell inside it: "top left square, centre cell". A declared game's cells are
"row two, column three" (the spoken form its rules parse, `ncbot.envs.rules.Declared.parse_cell`). Only an exact phrase is a cell;
anything else heard (nothing, half a phrase, extra words) is no cell, and the robot asks again.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from ncbot.envs.rules import NUMBER_WORDS
from ncbot.speech.asr import Recogniser
from ncbot.speech.hearing import HeardUtterance, say_in_noise_and_hear
from ncbot.speech.tts import PERSON_VOICE, SpeechCache, Voice

#: 3 (noughts & crosses), 9 (ultimate) or a declared game's (rows, cols), as `ncbot.vision.sheet.Grid`.
Grid = int | tuple[int, int]

ROWS, COLUMNS = ("top", "middle", "bottom"), ("left", "middle", "right")
CONFIRM_YES, CONFIRM_NO = "yes, that is right", "no, that is wrong"


def position_phrase(index: int) -> str:
    """Where `index` (0-8, row-major) lies in a 3x3 square: "top left" ... "centre" ... "bottom right"."""
    if not 0 <= index < 9:
        raise ValueError(f"a position in a 3x3 square is 0-8; got {index}")
    row, column = divmod(index, 3)
    return "centre" if index == 4 else f"{ROWS[row]} {COLUMNS[column]}"


def grid_shape(grid: Grid) -> tuple[int, int]:
    """(rows, cols) of a grid."""
    return grid if isinstance(grid, tuple) else (grid, grid)


def cell_phrase(cell: int, grid: Grid) -> str:
    """What a person says for `cell` (row-major) of a 3x3 or 9x9 board, or of a declared game's (rows, cols) grid
    (commas are pauses, not words)."""
    if isinstance(grid, tuple):
        rows, cols = grid
        if not 0 <= cell < rows * cols:
            raise ValueError(f"cell must be 0-{rows * cols - 1} of a {rows}x{cols} grid; got cell {cell}")
        row, column = divmod(cell, cols)
        return f"row {NUMBER_WORDS[row]}, column {NUMBER_WORDS[column]}"
    if grid == 3:
        return position_phrase(cell)
    if grid != 9 or not 0 <= cell < 81:
        raise ValueError(f"cell must be 0-{grid * grid - 1} of a 3x3 or 9x9 grid; got cell {cell}, grid {grid}")
    row, column = divmod(cell, 9)
    square, inner = (row // 3) * 3 + column // 3, (row % 3) * 3 + column % 3
    return f"{position_phrase(square)} square, {position_phrase(inner)} cell"


def words_of(text: str) -> tuple[str, ...]:
    """The recogniser's words for a phrase (lower case, no punctuation)."""
    return tuple(text.replace(",", " ").lower().split())


def cell_phrases(grid: Grid) -> dict[tuple[str, ...], int]:
    """Every cell's phrase, as words -> cell."""
    rows, cols = grid_shape(grid)
    return {words_of(cell_phrase(cell, grid)): cell for cell in range(rows * cols)}


def answer_sentences(grid: Grid) -> list[str]:
    """The LM corpus for "where did you draw?": each cell phrase once."""
    return [" ".join(words) for words in cell_phrases(grid)]


def confirm_sentences() -> list[str]:
    """The LM corpus for "did you say ...?": its two answers."""
    return [" ".join(words_of(CONFIRM_YES)), " ".join(words_of(CONFIRM_NO))]


def cell_of(words: Sequence[str], grid: Grid) -> int | None:
    """The cell an exact phrase names; None for anything else."""
    return cell_phrases(grid).get(tuple(words))


def yes_or_no(words: Sequence[str]) -> bool | None:
    """True for "yes" or "right" without "no" or "wrong", False the other way round, None otherwise."""
    yes, no = bool({"yes", "right"} & set(words)), bool({"no", "wrong"} & set(words))
    return None if yes == no else yes


class AnswerEars:
    """The person (``voice``) says an answer over ``kind`` noise at ``snr_db`` (a level, a (low, high) range drawn
    per utterance, or None = clean; noise from ``seed``), taken in by ``ears`` (default one microphone; Pepper's
    array in a room: ``ncbot.speech.ears.ArrayEars``) and the recogniser for the question hears it. Every answer
    is kept in ``log`` as a ``HeardUtterance`` whose ``understood`` is the cell heard (-1: no cell phrase) or, for a
    confirmation, 1 yes, 0 no, -1 neither."""

    def __init__(self, grid: Grid, cells: Recogniser | None = None, confirm: Recogniser | None = None,
                 voice: Voice = PERSON_VOICE,
                 snr_db: float | tuple[float, float] | None = None, kind: str = "babble",
                 babble_pool: Sequence[np.ndarray] = (), seed: int | Sequence[int] = 0,
                 cache: SpeechCache | None = None, ears=None) -> None:
        from ncbot.speech.ears import MonoEars

        if kind == "babble" and snr_db is not None and not babble_pool:
            raise ValueError("babble noise needs a babble_pool of other utterances (e.g. the robot's templates)")
        self.ears = ears if ears is not None else MonoEars(kind, babble_pool)
        self.grid = grid
        self.cells = cells if cells is not None else Recogniser(answer_sentences(grid))
        self.confirm = confirm if confirm is not None else Recogniser(confirm_sentences())
        self.voice, self.snr_db, self.kind, self.babble_pool = voice, snr_db, kind, list(babble_pool)
        self.cache = cache if cache is not None else SpeechCache()
        self.rng = np.random.default_rng(seed)
        self.log: list[HeardUtterance] = []

    def hear_cell(self, text: str) -> HeardUtterance:
        """The person says `text` for "where did you draw?"; ``understood``: the cell the words name, or -1."""
        return self._hear(text, self.cells, lambda words: -1 if (cell := cell_of(words, self.grid)) is None else cell)

    def hear_confirm(self, text: str) -> HeardUtterance:
        """The person says `text` for "did you say ...?"; ``understood``: 1 yes, 0 no, -1 neither."""
        return self._hear(text, self.confirm, lambda words: {True: 1, False: 0, None: -1}[yes_or_no(words)])

    def _hear(self, text: str, recogniser: Recogniser, meaning: Callable[[Sequence[str]], int]) -> HeardUtterance:
        utterance = say_in_noise_and_hear(text, recogniser, self.voice, self.cache, self.ears, self.snr_db, self.rng,
                                          lambda heard: meaning(heard.words), said=" ".join(words_of(text)))
        self.log.append(utterance)
        return utterance
