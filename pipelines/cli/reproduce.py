"""`ncbot reproduce`: the paper's table, claims and data budgets at a named budget (pipelines/reproduce/grid.py), and
the data each game needed, from finished runs (pipelines/reproduce/games_data.py)."""
from __future__ import annotations

import json
from typing import Optional

import typer

from ncbot.pipelines.cli.grid import (address_option, backend_option, make_cluster, partition_option, retries_option,
                                      sbatch_option, summary_lines, time_option)


def reproduce_command(
    part: str = typer.Argument("all", help="table | vision | budget | all | games-data (the data each game needed, "
                                "read from finished run folders: no run starts) | memory (temporal information three "
                                "ways, read from the runs folders of `ncbot ablate` grids such as memory_question, or from the "
                                "table_seeds.csv an earlier memory report wrote)."),
    run_dirs: Optional[list[str]] = typer.Argument(None, help="games-data: finished `ncbot train` run folders "
                                                    "(config.yaml, run.json, eval.json), one table row each; memory: "
                                                    "the runs folders `ncbot ablate` wrote and seeds CSVs of earlier "
                                                    "memory reports (one report)."),
    budget: Optional[str] = typer.Option(None, "--budget", help="quick (smoke, < 30 min on 2 cores, labelled) | full "
                                         "(the paper's protocol, resumable); every part but games-data."),
    workers: int = typer.Option(2, "--workers", help="Training runs in parallel."),
    out: str = typer.Option("results", "--out", "-o", help="Folder for paper_table.md, paper_claims.md, data_budget.md, vision_experiments.md, games_data.md and PNGs."),
    runs: str = typer.Option("runs/reproduce", "--runs", help="Folder for the training runs (one subfolder per budget): "
                              "a working folder, apart from --out, because runs are large and resumed while reports are small and shared."),
    backend: str = backend_option(),
    retries: int = retries_option(),
    address: Optional[str] = address_option(),
    partition: Optional[str] = partition_option(),
    time_limit: Optional[str] = time_option(),
    sbatch: Optional[list[str]] = sbatch_option(),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object (budget: {vision, dialogues, games})."),
    report_only: bool = typer.Option(False, "--report-only", help="table only: start no run, write the table and "
                                     "claims from the runs finished so far (marked PARTIAL until all are done)."),
) -> None:
    """Reproduce the paper's findings with the faithful options: runs (finished ones skipped), table, claims, budgets."""
    import shlex
    import sys

    from ncbot.pipelines.reproduce.grid import reproduce

    command = "ncbot " + shlex.join(sys.argv[1:])
    if part == "games-data":
        from ncbot.pipelines.reproduce.games_data import write_games_data

        if budget is not None:
            raise ValueError("games-data reads finished run folders; it takes no --budget")
        written = write_games_data(run_dirs or [], out, command)
        typer.echo(json.dumps(written) if as_json else f"{written['runs']} runs; wrote {', '.join(written['files'])}")
        return
    if part == "memory":
        from ncbot.pipelines.reproduce.memory import write_memory_report

        if budget is not None or not run_dirs:
            raise ValueError("memory reads runs folders written by `ncbot ablate` or an earlier report's seeds CSV "
                             "(e.g. ncbot reproduce memory results/memory/table_seeds.csv runs/memory_ultimate --out "
                             "results/memory); it takes no --budget")
        written = write_memory_report(list(run_dirs), out, command)
        typer.echo(json.dumps(written) if as_json else
                   f"{written['runs']} runs in {written['arms']} arms; wrote {', '.join(written['files'])}")
        return
    if run_dirs:
        raise ValueError(f"only games-data and memory take run folders; part {part!r} got {' '.join(run_dirs)}")
    if budget is None:
        raise ValueError(f"part {part!r} needs --budget quick | full")
    cluster = make_cluster(backend, workers, retries, address, partition=partition, time_limit=time_limit,
                           sbatch=sbatch)
    result = reproduce(part, budget, out=out, runs=runs, cluster=cluster, command=command, report_only=report_only)
    if as_json:
        report = result.get("budget_report")
        if part == "budget":
            typer.echo(json.dumps({key: report[key] for key in ("vision", "dialogues", "games", "label")}))
        elif part == "vision":
            typer.echo(json.dumps({key: result["vision_report"][key] for key in ("vision", "label")}))
        else:
            typer.echo(json.dumps(result))
        return
    if "vision_report" in result:
        typer.echo(f"{result['vision_report']['label']}\nwrote {', '.join(result['vision_report']['files'])}")
    if "runs" not in result:  # the vision part trains no RL agents; --report-only starts none
        if "table" in result:
            table = result["table"]
            typer.echo(f"{table['finished_runs']} of {table['planned_runs']} runs finished; wrote {table['table']} "
                       f"and {table['claims_file']}")
        return
    summary = result["runs"]
    typer.echo(result["label"])
    typer.echo("\n".join(summary_lines(summary)) + f"; runs in {summary['runs_dir']}")
    dialogue_runs = result.get("dialogue_runs")
    if dialogue_runs:
        typer.echo("dialogue budget: " + "\n".join(summary_lines(dialogue_runs)) +
                   f"; runs in {dialogue_runs['runs_dir']}")
    if "table" in result:
        typer.echo(f"wrote {result['table']['table']} and {result['table']['claims_file']}")
    if "budget_report" in result:
        typer.echo(f"wrote {out}/data_budget.md and {', '.join(result['budget_report']['figures'])}")
    if summary["unfinished"] or (dialogue_runs or {}).get("unfinished"):
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    """Add this area's command to the root app."""
    app.command("reproduce")(reproduce_command)
