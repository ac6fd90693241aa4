"""`ncbot reproduce`: the paper's table, claims and data budgets at a named budget (pipelines/reproduce/grid.py), and
the data each game needed, from finished runs (pipelines/reproduce/games_data.py)."""
from __future__ import annotations

from typing import Optional

import typer

from ncbot.pipelines.cli.conventions import json_option, listing, no_progress_option, out_folder, print_json, wrote
from ncbot.pipelines.cli.grid import (address_option, backend_option, make_cluster, partition_option, retries_option,
                                      sbatch_option, summary_lines, time_option)

#: every part `ncbot reproduce` takes: the training parts (they need --budget) and the ones that read finished runs
TRAINING_PARTS = ("table", "vision", "budget", "all")
READING_PARTS = ("games-data", "memory")


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
    out: str = out_folder("results", "the reports: paper_table.md, paper_claims.md, data_budget.md, "
                          "vision_experiments.md, games_data.md and their PNGs."),
    runs: str = typer.Option("runs/reproduce", "--runs", help="Folder for the training runs (one subfolder per budget): "
                              "a working folder, apart from --out, because runs are large and resumed while reports are small and shared."),
    backend: str = backend_option(),
    retries: int = retries_option(),
    address: Optional[str] = address_option(),
    partition: Optional[str] = partition_option(),
    time_limit: Optional[str] = time_option(),
    sbatch: Optional[list[str]] = sbatch_option(),
    as_json: bool = json_option(),
    report_only: bool = typer.Option(False, "--report-only", help="table only: start no run, write the table and "
                                     "claims from the runs finished so far (marked PARTIAL until all are done)."),
    no_progress: bool = no_progress_option(),
) -> None:
    """Reproduce the paper's findings with the faithful options: runs (finished ones skipped), table, claims, budgets."""
    import shlex
    import sys

    from ncbot.pipelines.reproduce.grid import reproduce

    command = "ncbot " + shlex.join(sys.argv[1:])
    if part not in TRAINING_PARTS + READING_PARTS:
        raise ValueError(f"part must be one of {', '.join(TRAINING_PARTS + READING_PARTS)}; got {part!r}")
    if part == "games-data":
        from ncbot.pipelines.reproduce.games_data import write_games_data

        if budget is not None:
            raise ValueError("games-data reads finished run folders; it takes no --budget")
        written = write_games_data(run_dirs or [], out, command)
        _report_files(written, as_json, f"{written['runs']} runs")
        return
    if part == "memory":
        from ncbot.pipelines.reproduce.memory import write_memory_report

        if budget is not None or not run_dirs:
            raise ValueError("memory reads runs folders written by `ncbot ablate` or an earlier report's seeds CSV "
                             "(e.g. ncbot reproduce memory results/memory/table_seeds.csv runs/memory_ultimate --out "
                             "results/memory); it takes no --budget")
        written = write_memory_report(list(run_dirs), out, command)
        _report_files(written, as_json, f"{written['runs']} runs in {written['arms']} arms")
        return
    if run_dirs:
        raise ValueError(f"only games-data and memory take run folders; part {part!r} got {' '.join(run_dirs)}")
    if budget is None:
        raise ValueError(f"part {part!r} needs --budget quick | full")
    cluster = make_cluster(backend, workers, retries, address, partition=partition, time_limit=time_limit,
                           sbatch=sbatch)
    result = reproduce(part, budget, out=out, runs=runs, cluster=cluster, command=command, report_only=report_only)
    written = _written(result, out)
    if as_json:
        report = result.get("budget_report")
        if part == "budget":
            print_json({**{key: report[key] for key in ("vision", "dialogues", "games", "label")}, "written": written})
        elif part == "vision":
            print_json({**{key: result["vision_report"][key] for key in ("vision", "label")}, "written": written})
        else:
            print_json({**result, "written": written})
    else:
        _print_summary(result)
    if written:
        wrote(listing(written))
    summary, dialogue_runs = result.get("runs"), result.get("dialogue_runs")
    if (summary or {}).get("unfinished") or (dialogue_runs or {}).get("unfinished"):
        raise typer.Exit(1)


def _report_files(written: dict, as_json: bool, counted: str) -> None:
    """games-data and memory: what was read, and the report's files."""
    if as_json:
        print_json({**written, "written": written["files"]})
    else:
        typer.echo(counted)
    wrote(listing(written["files"]))


def _written(result: dict, out: str) -> list[str]:
    """The report files a reproduce part wrote (the runs folders are named in the text)."""
    files = list(result.get("vision_report", {}).get("files", []))
    if "table" in result:
        files += [result["table"]["table"], result["table"]["claims_file"]]
    if "budget_report" in result:
        files += [f"{out}/data_budget.md", *result["budget_report"]["figures"]]
    return [str(path) for path in files]


def _print_summary(result: dict) -> None:
    """The text of a training part: its label, the runs finished, skipped and failed, and where they are."""
    if "vision_report" in result:
        typer.echo(result["vision_report"]["label"])
    if "runs" not in result:  # the vision part trains no RL agents; --report-only starts none
        if "table" in result:
            table = result["table"]
            typer.echo(f"{table['finished_runs']} of {table['planned_runs']} runs finished")
        return
    summary = result["runs"]
    typer.echo(result["label"])
    typer.echo("\n".join(summary_lines(summary)) + f"; runs in {summary['runs_dir']}")
    dialogue_runs = result.get("dialogue_runs")
    if dialogue_runs:
        typer.echo("dialogue budget: " + "\n".join(summary_lines(dialogue_runs)) +
                   f"; runs in {dialogue_runs['runs_dir']}")


def register(app: typer.Typer) -> None:
    """Add this area's command to the root app."""
    app.command("reproduce")(reproduce_command)
