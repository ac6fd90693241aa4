"""Word alignment of what was said with what was heard (Levenshtein), the basis of the word error rate and of
the channel model's counts of which word came out for which went in."""
from __future__ import annotations

from collections.abc import Sequence


def align(said: Sequence[str], heard: Sequence[str]) -> list[tuple[int | None, int | None]]:
    """Pairs (said index, heard index) of a minimum-edit alignment: (i, j) match or substitution, (i, None) a
    deletion, (None, j) an insertion. Ties prefer substitution, then deletion (deterministic)."""
    n, m = len(said), len(heard)
    cost = [[0] * (m + 1) for _ in range(n + 1)]
    for i in range(n + 1):
        cost[i][0] = i
    for j in range(m + 1):
        cost[0][j] = j
    for i in range(1, n + 1):
        for j in range(1, m + 1):
            cost[i][j] = min(
                cost[i - 1][j - 1] + (said[i - 1] != heard[j - 1]), cost[i - 1][j] + 1, cost[i][j - 1] + 1
            )
    pairs: list[tuple[int | None, int | None]] = []
    i, j = n, m
    while i or j:
        if i and j and cost[i][j] == cost[i - 1][j - 1] + (said[i - 1] != heard[j - 1]):
            pairs.append((i - 1, j - 1))
            i, j = i - 1, j - 1
        elif i and cost[i][j] == cost[i - 1][j] + 1:
            pairs.append((i - 1, None))
            i -= 1
        else:
            pairs.append((None, j - 1))
            j -= 1
    return pairs[::-1]


def word_errors(said: Sequence[str], heard: Sequence[str]) -> int:
    """Substitutions + deletions + insertions of the best alignment (the numerator of the word error rate)."""
    return sum(
        1 for i, j in align(said, heard) if i is None or j is None or said[i] != heard[j]
    )
