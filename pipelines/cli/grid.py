"""`ncbot ablate`: a grid of training runs on this machine, a Ray cluster or Slurm (pipelines/grid/); the backend
options it shares with `ncbot reproduce`.

Light at import (typer only): the grid package is imported inside the command.
"""
from __future__ import annotations

from typing import Any, Optional

import typer

from ncbot.pipelines.cli.conventions import json_option, no_progress_option, out_folder, print_json, wrote
from ncbot.pipelines.outputs import check_writable_dir  # light: os and pathlib only

RETRIES_HELP = ("Times a run whose worker, node or ncbot train died is tried again, each from its last checkpoint "
                "(default 3: a loss is rare and costs at most one checkpoint interval; a run killed four times in a "
                "row is killing itself, e.g. out of memory). A run that fails on its own error is not retried.")


def backend_option() -> Any:
    return typer.Option("local", "--backend", help="local (processes of this machine), ray (a Ray cluster, "
                        "--address) or slurm (Slurm jobs through submitit, --partition/--time/--sbatch).")


def retries_option() -> Any:
    from ncbot.pipelines.grid.runner import DEFAULT_RETRIES

    return typer.Option(DEFAULT_RETRIES, "--retries", help=RETRIES_HELP)


def address_option() -> Any:
    return typer.Option(None, "--address", help="With --backend ray: HOST:PORT of a running Ray head (default: a "
                        "local instance); every node must see the runs folder at the same path.")


def partition_option() -> Any:
    return typer.Option(None, "--partition", help="With --backend slurm: the partition of every job.")


def time_option() -> Any:
    return typer.Option(None, "--time", help="With --backend slurm: each job's time limit, MINUTES, HH:MM:SS or "
                        "D-HH:MM:SS (default 2:00:00); a run past it is requeued and resumes from its checkpoint.")


def sbatch_option() -> Any:
    return typer.Option(None, "--sbatch", help="With --backend slurm: an extra sbatch option KEY=VALUE for every "
                        "job (repeat it), e.g. --sbatch mem=8G --sbatch account=myproj.")


def make_cluster(backend: str, workers: int, retries: int, address: Optional[str], gpus_per_run: float = 1.0,
                 partition: Optional[str] = None, time_limit: Optional[str] = None,
                 sbatch: Optional[list[str]] = None) -> Any:
    """The commands' options as a checked `Cluster` (one-line ValueError before anything is planned or written)."""
    from ncbot.pipelines.grid.runner import Cluster

    cluster = Cluster(backend=backend, workers=workers, retries=retries, address=address, gpus_per_run=gpus_per_run,
                      partition=partition, time_limit=time_limit, sbatch=tuple(sbatch or ()))
    cluster.check()
    return cluster


def summary_lines(summary: dict[str, Any]) -> list[str]:
    """The end of a grid: counts, then every retried run and why, every failed run and why."""
    held = f", {summary['held']} skipped (another ncbot is training them)" if summary["held"] else ""
    lines = [f"{summary['done']} runs finished, {summary.get('skipped', 0)} skipped (already done){held}, "
             f"{summary['failed']} failed, {len(summary['retried'])} retried"]
    for entry in summary["retried"]:
        died = len(entry["why"])
        lines.append(f"retried {entry['run']}: {died} {'try' if died == 1 else 'tries'} died ({'; '.join(entry['why'])})")
    for name, why in summary["failures"].items():
        lines.append(f"failed {name}: {why}")
    return lines


def ablate_command(
    config: str = typer.Argument(..., help="Ablation grid YAML: a file or a shipped name (ablation, ablation_paper, screening; ncbot configs lists them)."),
    overrides: Optional[list[str]] = typer.Argument(None, help="section.key=value overrides applied to every run of "
                                                    "the grid, e.g. collector.total_frames=20000 (finished runs in the "
                                                    "runs folder are skipped: give another --out for other values)."),
    seeds: int = typer.Option(3, "--seeds", help="Seeds per grid cell."),
    workers: int = typer.Option(2, "--workers", help="Runs in parallel."),
    backend: str = backend_option(),
    out: Optional[str] = out_folder(None, "the grid's runs, one run folder each (default from the grid file)."),
    only: Optional[str] = typer.Option(None, "--only", help="Run only cells whose name contains this text."),
    retries: int = retries_option(),
    address: Optional[str] = address_option(),
    gpus_per_run: float = typer.Option(1.0, "--gpus-per-run", min=0.01, max=8.0,
                                       help="With --backend ray: GPUs each CUDA run asks for (a fraction shares one)."),
    partition: Optional[str] = partition_option(),
    time_limit: Optional[str] = time_option(),
    sbatch: Optional[list[str]] = sbatch_option(),
    status: bool = typer.Option(False, "--status", help="Start nothing: print where every run of the grid stands "
                                "(finished, training now, queued, stopped, failed, not started; its tries), whatever "
                                "backend runs it, and the training time left."),
    as_json: bool = json_option(),
    no_progress: bool = no_progress_option(),
) -> None:
    """Run the grid game x agent x temporal x look-ahead x seed in parallel; finished runs are skipped, runs whose
    worker or node died are retried from their last checkpoint."""
    if status:
        from ncbot.pipelines.grid.status import grid_status, status_json, status_lines

        if workers <= 0:
            raise ValueError(f"--workers must be a positive number of parallel runs, got {workers}")
        statuses, left, record = grid_status(config, seeds=seeds, out=out, only=only, overrides=list(overrides or []))
        if as_json:
            print_json(status_json(statuses, left, record, workers))
        else:
            typer.echo("\n".join(status_lines(statuses, left, record, workers)))
        return
    cluster = make_cluster(backend, workers, retries, address, gpus_per_run, partition, time_limit, sbatch)
    if out is not None:
        check_writable_dir(out, "--out")
    from ncbot.pipelines.grid.runner import run_ablation

    summary = run_ablation(config, seeds=seeds, cluster=cluster, out=out, only=only, overrides=list(overrides or []))
    if as_json:
        print_json({**summary, "written": [str(summary["runs_dir"])]})
    else:
        typer.echo("\n".join(summary_lines(summary)))
    wrote(f"the runs to {summary['runs_dir']} (one folder per run; ncbot table {summary['runs_dir']} sums them up)")
    if summary["unfinished"]:
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    """Add this area's command to the root app."""
    app.command("ablate")(ablate_command)
