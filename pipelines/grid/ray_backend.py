"""`--backend ray` of `ncbot ablate` / `ncbot reproduce`: the planned runs as Ray tasks, locally or on a cluster.

Each task is one try of one run (pipelines/grid/attempt.py): its `ncbot train` dies with the task's worker
(pipelines/grid/tether.py), so a worker or node lost mid-run leaves no orphan holding the run folder. Ray itself never
retries a task (`RAY_MAX_RETRIES` = 0); a task lost with its worker or node (`ray.get` raises) is a try that died,
and the grid's ledger submits the run again, up to `--retries` times, wherever the cluster has room: it resumes from
the run's last periodic checkpoint in the shared folder.

Why a shared folder, checked first: each run is an `ncbot train` process that writes its folder (checkpoints, the
replay buffer, eval.json) while it runs and resumes from it when restarted, so the folder must outlive the node
and be where the head reads the results. Copying folders back after each run would lose that (a killed node loses
its checkpoints) and move gigabytes of replay buffers. So every node must see the head's runs folder at the same
absolute path (NFS or similar; a local instance trivially does): before any run starts, one probe task per alive
node looks for a file the head just wrote there and checks that it can import ncbot's package (`ncbot.pipelines`,
the installed name: a wheel install has no top-level `pipelines`); any node that cannot is one clear error naming it.
Ray is an optional extra (`pip install 'ncbot[ray]'`); importing this module does not need it.

What a task asks for is what its run uses (`task_resources`): `num_cpus` = the run's `train.num_threads`, and a GPU
(`gpus_per_run`, 1 by default, a fraction to share one) when its `train.device` is cuda / cuda:N, or auto on a
cluster that has GPUs (Ray then makes the assigned GPU the task's only visible one, so use cuda or auto there, not
cuda:N with N > 0). A run that asks for more than any node has is one error before anything starts, not a task that
waits forever.
"""
from __future__ import annotations

import os
import uuid
from pathlib import Path
from typing import Any, Sequence

from ncbot.pipelines.grid.attempt import Outcome

# A task whose worker dies (a node lost, the OOM killer) is NOT re-run by Ray but by the grid's ledger, which counts
# the try, records why it died in the run folder and names it in the summary; Ray's implicit retries (3) would restart
# `ncbot train` behind the head's back and hide the loss.
RAY_MAX_RETRIES = 0

SHARED_FOLDER_DOC = "mount it at the same absolute path on every node (e.g. NFS); docs/cluster.md"


def _probe(marker: str) -> tuple[str, str]:
    """On one node: (node address, '' if the head's marker is visible and ncbot importable, else what is wrong)."""
    import importlib.util

    import ray

    where = ray.util.get_node_ip_address()
    if not os.path.isfile(marker):
        return where, f"the runs folder {os.path.dirname(marker)} is not shared with node {where} (a file the head " \
                      f"wrote there is not visible): {SHARED_FOLDER_DOC}"
    if importlib.util.find_spec("ncbot.pipelines") is None:
        return where, f"node {where} cannot import ncbot (ncbot.pipelines): install the same ncbot there"
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
        refs = [(n, probe.options(scheduling_strategy=NodeAffinitySchedulingStrategy(n["NodeID"], soft=False))
                 .remote(str(marker))) for n in nodes]
        answers = [_probe_answer(node, ref) for node, ref in refs]
    finally:
        marker.unlink(missing_ok=True)
    problems = [problem for _, problem in answers if problem]
    if problems:
        raise ValueError(f"--backend ray: {problems[0]}")
    return [where for where, _ in answers]


def _probe_answer(node: dict[str, Any], ref: Any) -> tuple[str, str]:
    """A probe's answer; a node whose worker cannot even load the probe (no ncbot, another ncbot) is a problem too."""
    import ray

    try:
        return ray.get(ref)
    except ray.exceptions.RayError as error:
        where = node.get("NodeManagerAddress", node.get("NodeID", "?"))
        first = next((line.strip() for line in str(error).splitlines() if "Error" in line), type(error).__name__)
        return where, f"node {where} cannot run ncbot's tasks ({first[:200]}): install the same ncbot there"


def task_resources(threads: int, device: str, cluster_gpus: float, gpus_per_run: float = 1.0) -> dict[str, float]:
    """The Ray resources of one run: its torch threads as CPUs, and `gpus_per_run` GPUs when its `train.device`
    is cuda / cuda:N, or auto where the cluster has a GPU (auto on a CPU-only cluster is a CPU run)."""
    wants_gpu = device.startswith("cuda") or (device == "auto" and cluster_gpus > 0)
    return {"num_cpus": float(threads), "num_gpus": float(gpus_per_run) if wants_gpu else 0.0}


def check_fits(demands: Sequence[tuple[str, dict[str, float]]], nodes: Sequence[dict[str, float]]) -> None:
    """ValueError naming the first run whose CPUs and GPUs no single alive node has (it would wait forever)."""
    for name, demand in demands:
        if not any(node.get("CPU", 0) >= demand["num_cpus"] and node.get("GPU", 0) >= demand["num_gpus"]
                   for node in nodes):
            have = ", ".join(f"{node.get('CPU', 0):g} CPU/{node.get('GPU', 0):g} GPU" for node in nodes) or "none"
            raise ValueError(f"--backend ray: run {name} asks for {demand['num_cpus']:g} CPUs (train.num_threads) and "
                             f"{demand['num_gpus']:g} GPUs (train.device), more than any node has ({have}); lower "
                             "train.num_threads, use train.device=cpu or add a node with a GPU")


def lost_why(error: Exception) -> str:
    """Why a task was lost, in a user's words (the ledger's "died" reason)."""
    kind = type(error).__name__
    reasons = {"WorkerCrashedError": "its Ray worker died (killed, or lost with its node)",
               "NodeDiedError": "its Ray node was lost",
               "OutOfMemoryError": "Ray's memory monitor killed its worker (the node ran short of memory)",
               "TaskCancelledError": "its Ray task was cancelled"}
    return f"{reasons.get(kind, 'Ray lost the task')} ({kind})"


def _ray_try(run: Any, try_number: int) -> Any:
    """The Ray task: one try of one run on the node Ray chose (pipelines/grid/attempt.py)."""
    import ray

    from ncbot.pipelines.grid.attempt import run_attempt

    return run_attempt(run, backend="ray", try_number=try_number, node=ray.get_runtime_context().get_node_id()[:12])


def _connect(address: str | None, workers: int, described: Sequence[tuple[str, int, str]]) -> None:
    """Start a local instance (``address`` None: CPUs for ``workers`` runs at the largest thread count, and the
    machine's GPUs) or join the cluster at HOST:PORT ("auto": the one this machine belongs to)."""
    import ray

    try:
        if address is None:
            threads = max((threads for _, threads, _ in described), default=1)
            ray.init(num_cpus=workers * threads, include_dashboard=False, ignore_reinit_error=True,
                     log_to_driver=False)
        else:
            ray.init(address=address, ignore_reinit_error=True, log_to_driver=False)
    except Exception as error:  # ray raises ConnectionError, RuntimeError or its own AuthenticationError
        first_line = str(error).strip().splitlines()[0][:200] if str(error).strip() else type(error).__name__
        raise ValueError(f"--address {address}: cannot connect to a Ray cluster there ({first_line}); expected the "
                         f"HOST:PORT of a running `ray start --head` (a head with token authentication also needs "
                         f"RAY_AUTH_MODE=token and its token here, docs/cluster.md)") from None


def run_on_ray(todo: Sequence[Any], ledger: Any) -> None:
    """Every planned run as Ray tasks, at most ``workers`` at a time, each asking for the resources its run uses
    (module doc); a lost task is settled as died and, if the ledger says so, submitted again.

    ``ledger.cluster.address`` None starts a local instance, else connects to that cluster (a connection made
    before, e.g. by a test, is used as it is). Run folders must be absolute and under ``ledger.runs_dir``, which every
    node must see (checked first)."""
    import ray

    cluster = ledger.cluster
    described = [run.settings() for run in todo]
    started = not ray.is_initialized()
    if started:
        _connect(cluster.address, cluster.workers, described)
    try:
        check_shared_folder(ledger.runs_dir)
        nodes = [n.get("Resources", {}) for n in ray.nodes() if n.get("Alive")]
        cluster_gpus = sum(node.get("GPU", 0) for node in nodes)
        demands = {name: task_resources(threads, device, cluster_gpus, cluster.gpus_per_run)
                   for name, threads, device in described}
        check_fits(list(demands.items()), nodes)
        remote = ray.remote(max_retries=RAY_MAX_RETRIES)(_ray_try)
        waiting, pending = list(todo), {}
        while waiting or pending:
            while waiting and len(pending) < cluster.workers:
                run = waiting.pop(0)
                pending[remote.options(**demands[run.name]).remote(run, ledger.next_try(run))] = run
            ready, _ = ray.wait(list(pending), num_returns=1)
            run = pending.pop(ready[0])
            try:
                outcome = ray.get(ready[0])
            except ray.exceptions.RayTaskError as error:  # ncbot's code raised on the node: the same on a retry
                last = str(error).strip().splitlines()[-1][:200]
                outcome = Outcome(run.name, "failed", f"error on the Ray node: {last}")
            except ray.exceptions.RayError as error:
                outcome = Outcome(run.name, "died", lost_why(error))
            if ledger.settle(run, outcome):
                waiting.insert(0, run)
    finally:
        if started:
            ray.shutdown()
