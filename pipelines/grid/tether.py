"""`python -m ncbot.pipelines.grid.tether PARENT_PID -- COMMAND ...`: run COMMAND so that it dies with its parent.

Why: a grid's `ncbot train` is the child of whatever runs the try (a local pool thread, a Ray worker, a Slurm job).
When that parent is SIGKILLed (a Ray worker killed, the OOM killer, a node's raylet gone), an ordinary child lives on,
an orphan that keeps training and holds the run folder's lock, so the retry of the run elsewhere finds it in use.
On Linux the kernel can signal a child when its parent dies (prctl PR_SET_PDEATHSIG), and the setting survives
`execve`: this small launcher sets it, checks that its parent did not die in between (it would then have been
re-parented already and never be signalled), and replaces itself with COMMAND. SIGKILL, not SIGTERM: nobody reads
the orphan's output any more, its lock must go at once, and a training killed anywhere resumes from its last
periodic checkpoint (checkpoints are written atomically). Elsewhere (macOS) COMMAND runs untethered.

Light on purpose: it runs before every `ncbot train` of a grid; it imports nothing of ncbot's but its package.
"""
from __future__ import annotations

import os
import signal
import sys

PR_SET_PDEATHSIG = 1  # <linux/prctl.h>
PARENT_GONE_EXIT = 137  # as if SIGKILLed with the parent: the grid counts the try as died and retries it


def tie_to_parent(parent_pid: int) -> bool:
    """Ask the kernel to SIGKILL this process when its parent dies; False when the parent is gone already."""
    if sys.platform.startswith("linux"):
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) != 0:
            return os.getppid() == parent_pid  # no prctl (a sandbox): at least not started as an orphan
    return os.getppid() == parent_pid


def tethered(command: list[str]) -> list[str]:
    """``command`` run through this launcher, tied to the calling process."""
    return [sys.executable, "-m", "ncbot.pipelines.grid.tether", str(os.getpid()), "--", *command]


def main(argv: list[str]) -> None:
    if len(argv) < 3 or argv[1] != "--" or not argv[0].isdigit():
        print("usage: python -m ncbot.pipelines.grid.tether PARENT_PID -- COMMAND ...", file=sys.stderr)
        sys.exit(2)
    if not tie_to_parent(int(argv[0])):
        sys.exit(PARENT_GONE_EXIT)
    command = argv[2:]
    os.execvp(command[0], command)


if __name__ == "__main__":
    main(sys.argv[1:])
