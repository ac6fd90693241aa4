"""Progress that fits where it goes: a tqdm bar (rate, ETA) on a terminal, plain lines every ~10 % in a pipe or log.

Why: tqdm redraws with carriage returns; in a piped or logged output every redraw becomes text (`ncbot train > log`
wrote one redraw per collector batch). When the stream is not a terminal, `progress_bar` returns a `LineProgress`
that prints one self-contained line each time another tenth of the total is done (and at the end), with the rate
and the ETA. Both objects offer the tqdm calls ncbot uses: iteration, `update`, `set_postfix(_str)`, `close`, `with`.

Three rules hold for both: the count never reads past 100 % (work that overruns its estimate, such as whole collector
batches past a frame budget, grows the total instead); a bar left by an error is not drawn again, so the error's one
line stands alone; and `--no-progress` (`silence()`) turns every bar of the process off.
"""
from __future__ import annotations

import sys
import time
from collections.abc import Iterable, Iterator
from typing import IO, Any

STEPS = 10  # plain lines per run in line mode: one every 10 %
UNTIMED_EVERY_S = 60.0  # line mode without a known total: one line a minute
_silenced = False  # `--no-progress`: no bar anywhere in this process


def silence(off: bool = True) -> None:
    """Turn every progress bar of this process off (`--no-progress`), or back on with `off=False`."""
    global _silenced
    _silenced = off


def silenced() -> bool:
    return _silenced


def is_terminal(stream: IO[str]) -> bool:
    """True when `stream` is an interactive terminal (redraws render in place)."""
    try:
        return stream.isatty()
    except (AttributeError, ValueError):  # closed or file-like without a descriptor
        return False


def duration(seconds: float) -> str:
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    return f"{hours}:{rest // 60:02d}:{rest % 60:02d}" if hours else f"{rest // 60}:{rest % 60:02d}"


def _amount(value: float, scale: bool) -> str:
    if not scale:
        return f"{value:g}" if isinstance(value, float) else str(value)
    for factor, suffix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if abs(value) >= factor:
            return f"{value / factor:.1f}{suffix}"
    return f"{value:.0f}"


def rate_text(rate: float) -> str:
    """A rate as people read it: 7.5k, 310, 4.2, 0.35 (never 7.46e+03)."""
    if rate >= 1000:
        return _amount(rate, True)
    return f"{rate:.0f}" if rate >= 100 else f"{rate:.1f}" if rate >= 1 else f"{rate:.2f}"


class LineProgress:
    """tqdm's interface, printing one plain line per ~10 % of `total` (rate and ETA) instead of redraws."""

    def __init__(self, iterable: Iterable | None = None, *, total: float | None = None, desc: str = "",
                 unit: str = "it", unit_scale: bool = False, initial: float = 0, stream: IO[str] | None = None,
                 steps: int = STEPS) -> None:
        self.iterable = iterable
        if total is None and iterable is not None and hasattr(iterable, "__len__"):
            total = len(iterable)
        if total and initial > total:  # resumed past its estimate: never more than 100 %
            total = initial
        self.total, self.desc, self.unit, self.unit_scale = total, desc, unit, unit_scale
        self.n = self.initial = initial
        self.stream = stream if stream is not None else sys.stderr
        self.steps = steps
        self.postfix = ""
        self.started = self.last_line = time.monotonic()
        self.printed = self._step(initial)  # the tenths already reported (a resumed run starts part-way)
        self.closed = False

    def _step(self, n: float) -> int:
        return int(self.steps * n / self.total) if self.total else 0

    def __iter__(self) -> Iterator:
        for item in self.iterable:
            yield item
            self.update(1)
        self.close()

    def __enter__(self) -> LineProgress:
        return self

    def __exit__(self, exc_type: Any, *exc: Any) -> None:
        if exc_type is not None:  # an error's one line stands alone: no closing progress line before it
            self.closed = True
        self.close()

    def update(self, n: float = 1) -> None:
        self.n += n
        if self.total and self.n > self.total:  # the work overran its estimate: never more than 100 %
            self.total = self.n
        now = time.monotonic()
        if self.total:
            if self._step(self.n) > self.printed and self.n < self.total:
                self.printed = self._step(self.n)
                self._print(now)
        elif now - self.last_line >= UNTIMED_EVERY_S:
            self._print(now)

    def set_postfix(self, refresh: bool = True, **values: Any) -> None:
        self.postfix = ", ".join(f"{key}={value}" for key, value in values.items())

    def set_postfix_str(self, text: str = "", refresh: bool = True) -> None:
        self.postfix = text

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            self._print(time.monotonic())

    def line(self, now: float) -> str:
        """`desc: 40% 240.0k/602.1k frame [1:02 elapsed, ETA 1:30, 3.9k frame/s] eps=0.1`."""
        elapsed = now - self.started
        done = self.n - self.initial
        rate = done / elapsed if elapsed > 0 else 0.0
        parts = [f"{self.desc}: " if self.desc else ""]
        if self.total:
            parts.append(f"{100 * self.n / self.total:3.0f}% {_amount(self.n, self.unit_scale)}/"
                         f"{_amount(self.total, self.unit_scale)} {self.unit}")
            eta = (self.total - self.n) / rate if rate > 0 else float("nan")
            timing = f"{duration(elapsed)} elapsed, ETA {duration(eta) if eta == eta else '?'}"
        else:
            parts.append(f"{_amount(self.n, self.unit_scale)} {self.unit}")
            timing = f"{duration(elapsed)} elapsed"
        parts.append(f" [{timing}, {rate_text(rate)} {self.unit}/s]")
        if self.postfix:
            parts.append(f" {self.postfix}")
        return "".join(parts)

    def _print(self, now: float) -> None:
        self.last_line = now
        print(self.line(now), file=self.stream, flush=True)


class _Silent(LineProgress):
    """disable=True: counts, prints nothing."""

    def _print(self, now: float) -> None:
        pass


def progress_bar(iterable: Iterable | None = None, *, total: float | None = None, desc: str = "", unit: str = "it",
                 unit_scale: bool = False, initial: float = 0, disable: bool = False, leave: bool = True,
                 stream: IO[str] | None = None):
    """A tqdm bar on a terminal, else a `LineProgress` (one line per ~10 %); `disable` silences both."""
    stream = stream if stream is not None else sys.stderr
    if disable or _silenced:
        return _Silent(iterable, total=total, desc=desc, unit=unit, initial=initial, stream=stream)
    if not is_terminal(stream):
        return LineProgress(iterable, total=total, desc=desc, unit=unit, unit_scale=unit_scale, initial=initial,
                            stream=stream)
    return _terminal_bar()(iterable, total=total, desc=desc, unit=unit, unit_scale=unit_scale, initial=initial,
                           leave=leave, file=stream, dynamic_ncols=True)


def _terminal_bar() -> type:
    """tqdm with the rules of `LineProgress`: the total grows with overrunning work, and an error clears the bar."""
    from tqdm import tqdm

    class TerminalBar(tqdm):
        def update(self, n: float = 1) -> bool | None:
            if self.total and self.n + n > self.total:
                self.total = self.n + n
            return super().update(n)

        def __exit__(self, exc_type: Any, *exc: Any) -> None:
            if exc_type is not None:
                self.leave = False  # tqdm then erases the bar: the error's line stands alone
            super().__exit__(exc_type, *exc)

    return TerminalBar
