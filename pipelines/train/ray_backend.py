"""`--backend ray` of `ncbot ablate` / `ncbot reproduce`: the planned runs as Ray tasks, locally or on a cluster.

Why a shared folder, checked first: each run is an `ncbot train` process that writes its folder (checkpoints, the
replay buffer, eval.json) while it runs and resumes from it when restarted, so the folder must outlive the node
and be where the head reads the results. Copying folders back after each run would lose that (a killed node loses
its checkpoints) and move gigabytes of replay buffers. So every node must see the head's runs folder at the same
absolute path (NFS or similar; a local instance trivially does): before any run starts, one probe task per alive
node looks for a file the head just wrote there and checks that it can import ncbot; any node that cannot is one
clear error naming it. Ray is an optional extra (`pip install 'ncbot[ray]'`); importing this module does not need it.
"""
from __future__ import annotations

import os
import uuid
from pathlib import Path
from typing import Any, Callable, Sequence

SHARED_FOLDER_DOC = ("mount it at the same absolute path on every node (e.g. NFS); docs/reproduction.md, "
                     "'Past one machine'")


def ray_available() -> bool:
    try:
        import ray  # noqa: F401
    except ImportError:
        return False
    return True


def _probe(marker: str) -> tuple[str, str]:
    """On one node: (node address, '' if the head's marker is visible and ncbot importable, else what is wrong)."""
    import importlib.util

    import ray

    where = ray.util.get_node_ip_address()
    if not os.path.isfile(marker):
        return where, f"the runs folder {os.path.dirname(marker)} is not shared with node {where} (a file the head " \
                      f"wrote there is not visible): {SHARED_FOLDER_DOC}"
    if importlib.util.find_spec("pipelines") is None:
        return where, f"node {where} cannot import ncbot's pipelines package: install the same ncbot there"
    return where, ""


def check_shared_folder(runs_dir: Path) -> list[str]:
    """Probe every alive node with CPUs (ray must be initialised); ValueError naming the first node that fails.
    Returns the probed nodes' addresses."""
    import ray
    from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

    runs_dir.mkdir(parents=True, exist_ok=True)
    marker = runs_dir / f".ncbot-ray-probe-{uuid.uuid4().hex}"
    marker.write_text("written by the head of `--backend ray`; removed after the check\n")
    try:
        nodes = [n for n in ray.nodes() if n.get("Alive") and n.get("Resources", {}).get("CPU", 0) > 0]
        probe = ray.remote(num_cpus=0)(_probe)
        answers = ray.get([probe.options(scheduling_strategy=NodeAffinitySchedulingStrategy(n["NodeID"], soft=False))
                           .remote(str(marker)) for n in nodes])
    finally:
        marker.unlink(missing_ok=True)
    problems = [problem for _, problem in answers if problem]
    if problems:
        raise ValueError(f"--backend ray: {problems[0]}")
    return [where for where, _ in answers]


def run_on_ray(todo: Sequence[Any], run_one: Callable[[Any], tuple[str, int]], *, workers: int, address: str | None,
               runs_dir: Path, on_done: Callable[[str, int], None]) -> None:
    """Run ``run_one(run)`` for every planned run as a Ray task (1 CPU each), at most ``workers`` at a time.

    ``address`` None starts a local instance with ``workers`` CPUs; else connects to the cluster at HOST:PORT (or
    "auto"). Run folders must be absolute and under ``runs_dir``, which every node must see (checked first).
    """
    import ray

    started = not ray.is_initialized()
    try:
        if address is None:
            ray.init(num_cpus=workers, include_dashboard=False, ignore_reinit_error=True, log_to_driver=False)
        else:
            ray.init(address=address, ignore_reinit_error=True, log_to_driver=False)
    except Exception as error:  # ray raises ConnectionError, RuntimeError or its own AuthenticationError
        first_line = str(error).strip().splitlines()[0][:200] if str(error).strip() else type(error).__name__
        raise ValueError(f"--address {address}: cannot connect to a Ray cluster there ({first_line}); expected the "
                         f"HOST:PORT of a running `ray start --head` (a head with token authentication also needs "
                         f"RAY_AUTH_MODE=token and its token here, docs/reproduction.md)") from None
    try:
        check_shared_folder(runs_dir)
        remote = ray.remote(num_cpus=1)(run_one)
        waiting, pending = list(todo), []
        while waiting or pending:
            while waiting and len(pending) < workers:
                pending.append(remote.remote(waiting.pop(0)))
            ready, pending = ray.wait(pending, num_returns=1)
            on_done(*ray.get(ready[0]))
    finally:
        if started:
            ray.shutdown()
