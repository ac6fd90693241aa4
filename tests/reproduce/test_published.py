"""Every published table and verdict in results/ that is made from per-seed data is re-made, byte for byte, from the
per-seed CSV shipped beside it, by the command its first lines name; and the steps that join published runs are
checked on the shipped CSVs themselves (no run folder is needed: none is shipped)."""
from __future__ import annotations

import csv
import re
import shutil
from pathlib import Path

import pytest

from ncbot.pipelines.reproduce.claims import evaluate_claims
from ncbot.pipelines.reproduce.memory import write_memory_report
from ncbot.pipelines.reproduce.table import write_report
from ncbot.pipelines.reproduce.two_sample import welch_greater

RESULTS = Path(__file__).resolve().parents[2] / "results"
# (seeds CSV, the table, its claims): each re-made with `ncbot table CSV --out TABLE --claims CLAIMS`
TABLES = [("paper_table_seeds.csv", "paper_table.md", "paper_claims.md"),
          ("temporal/table_seeds.csv", "temporal/table.md", "temporal/claims.md"),
          ("readings/screening_seeds.csv", "readings/screening.md", "readings/screening_claims.md")]


def _made_by(path: Path) -> str:
    found = re.search(r"Made by `([^`]+)`", path.read_text(encoding="utf-8"))
    assert found, f"{path} names no command"
    return found.group(1)


@pytest.mark.parametrize("seeds, table, claims", TABLES)
def test_a_published_table_and_its_claims_are_remade_from_its_seeds_csv(tmp_path: Path, seeds: str, table: str,
                                                                         claims: str) -> None:
    command = _made_by(RESULTS / table)
    assert command == f"ncbot table results/{seeds} --out results/{table} --claims results/{claims}"
    source = tmp_path / Path(seeds).name
    shutil.copyfile(RESULTS / seeds, source)
    out = tmp_path / "out"
    write_report(source, out / Path(table).name, out / Path(claims).name, command=command)
    for published, made in ((table, Path(table).name), (claims, Path(claims).name), (seeds, Path(seeds).name)):
        assert (out / made).read_bytes() == (RESULTS / published).read_bytes(), published


def test_the_memory_report_is_remade_from_its_seeds_and_curves_csvs(tmp_path: Path) -> None:
    command = _made_by(RESULTS / "memory" / "table.md")
    assert command == "ncbot reproduce memory results/memory/table_seeds.csv --out results/memory"
    for name in ("table_seeds.csv", "table_curves.csv"):
        shutil.copyfile(RESULTS / "memory" / name, tmp_path / name)
    write_memory_report([tmp_path / "table_seeds.csv"], tmp_path / "out", command)
    for name in ("table.md", "table_seeds.csv", "table_curves.csv"):
        assert (tmp_path / "out" / name).read_bytes() == (RESULTS / "memory" / name).read_bytes(), name


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def test_the_ultimate_100_proposed_rows_are_the_memory_reports_paper_arms() -> None:
    """The paper table's two Proposed rows on Ultimate (100) hold seeds 0-9: seeds 0-4 from `ncbot reproduce table
    --budget full`, seeds 5-9 from `ncbot ablate memory_ultimate --seeds 10 --only paper/` placed beside them. Both
    CSVs ship; the same runs (run ids) carry the same numbers in both, so claim (ii)'s verdict on that row follows
    from the memory report's CSV alone."""
    paper = [row for row in _rows(RESULTS / "paper_table_seeds.csv")
             if row["game"] == "ultimate100" and row["agent"].startswith("proposed")]
    memory = {row["run_id"]: row for row in _rows(RESULTS / "memory" / "table_seeds.csv")
              if row["game"] == "ultimate" and row["memory"] == "none" and row["batch_size"] == "2"}
    assert len(paper) == 20 and len(memory) == 20
    for row in paper:
        twin = memory[row["run_id"]]
        assert (twin["seed"], twin["temporal"]) == (row["seed"], str(row["agent"] == "proposed-temporal").lower())
        for column in ("frames", "first.task_success", "first.win", "first.avg_length", "second.task_success"):
            assert twin[column] == row[column], column
    samples = {("paper", "ultimate100", cell): {"task_success": [float(row["first.task_success"]) for row in sorted(
        memory.values(), key=lambda row: int(row["seed"])) if (row["temporal"] == "true") == (cell == "proposed-temporal")]}
        for cell in ("proposed-temporal", "proposed-notemporal")}
    (claim_ii,) = evaluate_claims(samples)
    assert claim_ii.claim == "ii" and f"| {claim_ii.p:.4f} |" in (RESULTS / "paper_claims.md").read_text()
    assert claim_ii.verdict == "reproduced"


def test_the_planned_earlier_never_test_follows_from_the_shipped_csvs() -> None:
    """results/readings/earlier_never_test.md (`ncbot compare` on run folders) from the two CSVs its runs are in."""
    screening = [float(row["first.task_success"]) for row in _rows(RESULTS / "readings" / "screening_seeds.csv")
                 if row["suite"] == "earlier_never" and row["agent"] == "proposed-temporal" and 2 <= int(row["seed"]) <= 7]
    paper = [float(row["first.task_success"]) for row in _rows(RESULTS / "memory" / "table_seeds.csv")
             if row["game"] == "ultimate" and row["memory"] == "none" and row["batch_size"] == "2"
             and row["temporal"] == "true"]
    t, df, p = welch_greater(screening, paper)
    assert (len(screening), len(paper)) == (6, 10)
    assert f"t = {t:.2f}, df = {df:.1f}, p = {p:.4f}" in (RESULTS / "readings" / "earlier_never_test.md").read_text()
