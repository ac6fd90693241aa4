"""`--backend ray` of `ncbot ablate` / `ncbot reproduce`: the planned runs as Ray tasks, locally or on a cluster.

Why a shared folder, checked first: each run is an `ncbot train` process that writes its folder (checkpoints, the
replay buffer, eval.json) while it runs and resumes from it when restarted, so the folder must outlive the node
and be where the head reads the results. Copying folders back after each run would lose that (a killed node loses
its checkpoints) and move gigabytes of replay buffers. So every node must see the head's runs folder at the same
absolute path (NFS or similar; a local instance trivially does): before any run starts, one probe task per alive
node looks for a file the head just wrote there and checks that it can import ncbot; any node that cannot is one
clear error naming it. Ray is an optional extra (`pip install 'ncbot[ray]'`); importing this module does not need it.

What a task asks for is what its run uses (`task_resources`): `num_cpus` = the run's `train.num_threads`, and a GPU
(`gpus_per_run`, 1 by default, a fraction to share one) when its `train.device` is cuda / cuda:N, or auto on a
cluster that has GPUs (Ray then makes the assigned GPU the task's only visible one, so use cuda or auto there, not
cuda:N with N > 0). A run that asks for more than any node has is one error before anything starts, not a task that
waits forever. Retries are explicit: `RAY_MAX_RETRIES` = 0.
"""
from __future__ import annotations

import os
import uuid
from pathlib import Path
from typing import Any, Callable, Sequence

# A task whose worker dies (a node lost, the OOM killer) is NOT re-run by Ray: the run's folder keeps its periodic
# checkpoints and the next `ncbot ablate` / `ncbot reproduce` resumes it with `--resume` (counted as failed until
# then). Ray's implicit default (3 retries) would restart `ncbot train` behind the head's back, from a folder a dying
# process may still hold, and hide the failure from the summary.
RAY_MAX_RETRIES = 0

SHARED_FOLDER_DOC = ("mount it at the same absolute path on every node (e.g. NFS); docs/reproduction.md, "
                     "'Past one machine'")


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


def run_on_ray(todo: Sequence[Any], run_one: Callable[[Any], tuple[str, int]], *, workers: int, address: str | None,
               runs_dir: Path, on_done: Callable[[str, int], None],
               settings: Callable[[Any], tuple[str, int, str]] | None = None, gpus_per_run: float = 1.0) -> None:
    """Run ``run_one(run)`` for every planned run as a Ray task, at most ``workers`` at a time, each asking for the
    resources its run uses (module doc; ``settings(run)`` -> (name, train.num_threads, train.device), 1 CPU each
    when None), never retried by Ray (`RAY_MAX_RETRIES`).

    ``address`` None starts a local instance with CPUs for ``workers`` runs at the largest thread count (and the
    machine's GPUs); else connects to the cluster at HOST:PORT (or "auto"). Run folders must be absolute and under
    ``runs_dir``, which every node must see (checked first).
    """
    import ray

    described = [settings(run) if settings is not None else (str(run), 1, "cpu") for run in todo]
    started = not ray.is_initialized()
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
                         f"RAY_AUTH_MODE=token and its token here, docs/reproduction.md)") from None
    try:
        check_shared_folder(runs_dir)
        nodes = [n.get("Resources", {}) for n in ray.nodes() if n.get("Alive")]
        cluster_gpus = sum(node.get("GPU", 0) for node in nodes)
        demands = [(name, task_resources(threads, device, cluster_gpus, gpus_per_run))
                   for name, threads, device in described]
        check_fits(demands, nodes)
        remote = ray.remote(max_retries=RAY_MAX_RETRIES)(run_one)
        waiting, pending = list(zip(todo, demands)), []
        while waiting or pending:
            while waiting and len(pending) < workers:
                run, (_, demand) = waiting.pop(0)
                pending.append(remote.options(**demand).remote(run))
            ready, pending = ray.wait(pending, num_returns=1)
            on_done(*ray.get(ready[0]))
    finally:
        if started:
            ray.shutdown()
