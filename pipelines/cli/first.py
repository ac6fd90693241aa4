"""`--first robot|human`: the one CLI name for who opens a game (config `env.first`, MCAP/TensorDict `robot_first`).

The old spelling `--seat first|second` still works: it is mapped and a one-line note on stderr names the new one.
`--seat` always meant the seat of the command's subject: the robot's in `ncbot eval`, the person's in `ncbot play`.
"""
from __future__ import annotations

import typer

ROBOT_SEAT = {"robot": "first", "human": "second", "alternate": "alternate"}  # --first -> the robot's seat


def resolve_first(first: str | None, seat: str | None, *, allowed: tuple[str, ...], default: str,
                  seat_is_robot: bool = True) -> str:
    """The `--first` value of a command, from `--first` or the old `--seat` (mapped, with a note on stderr)."""
    if first is not None and seat is not None:
        raise ValueError("give --first only (--seat is its old spelling)")
    if seat is not None:
        opens, follows = ("robot", "human") if seat_is_robot else ("human", "robot")
        mapped = {"first": opens, "second": follows, "alternate": "alternate"}.get(seat)
        if mapped is None or mapped not in allowed:
            old = [s for s in ("first", "second", "alternate") if {"first": opens, "second": follows}.get(s, s) in allowed]
            raise ValueError(f"--seat must be {' or '.join(old)}, got {seat!r} (new spelling: --first {'|'.join(allowed)})")
        typer.echo(f"ncbot: note: --seat {seat} is the old spelling of --first {mapped}", err=True)
        first = mapped
    first = default if first is None else first
    if first not in allowed:
        raise ValueError(f"--first must be one of {', '.join(allowed)}, got {first!r}")
    return first
