"""`ncbot table <table>_seeds.csv`: the per-seed CSV a table writes stands in for its run folders (real report code,
real files): the same numbers, claims and verdicts, the same CSV written back, no curves; bad files are one line."""
from __future__ import annotations

from pathlib import Path

from ncbot.pipelines.reproduce.seeds_csv import read_seeds_csv
from ncbot.pipelines.reproduce.table import write_report
from tests.learning_helpers import ncbot
from tests.reproduce.test_table import _paper_tree


def _body(text: str) -> list[str]:
    """A report without its "Made by" line and without the row labels the run folders' config.yaml gives."""
    return [line.replace("(100, 100, 100)", "(100)") for line in text.splitlines() if not line.startswith("Made by")]


def test_the_seeds_csv_gives_back_the_table_and_the_verdicts(tmp_path: Path) -> None:
    _paper_tree(tmp_path / "runs", seeds=5, temporal_gain=0.02)
    from_runs = write_report(tmp_path / "runs", tmp_path / "a" / "t.md", tmp_path / "a" / "c.md")
    csv_path = tmp_path / "a" / "t_seeds.csv"
    from_csv = write_report(csv_path, tmp_path / "b" / "t.md", tmp_path / "b" / "c.md")
    assert _body(from_csv.table) == _body(from_runs.table)
    assert _body(from_csv.claims_text) == _body(from_runs.claims_text)
    assert [(c.claim, c.verdict, c.p) for c in from_csv.claims] == [(c.claim, c.verdict, c.p) for c in from_runs.claims]
    assert (tmp_path / "b" / "t_seeds.csv").read_bytes() == csv_path.read_bytes()  # written back byte for byte
    assert list((tmp_path / "a").glob("curves_*.png")) and not list((tmp_path / "b").glob("curves_*.png"))
    runs = read_seeds_csv(csv_path)[("paper", "standard", "proposed-temporal")]
    assert [run["seed"] for run in runs] == [0, 1, 2, 3, 4] and isinstance(runs[0]["first"]["games"], int)


def test_a_bad_seeds_csv_is_one_line_and_exit_2(tmp_path: Path) -> None:
    bad = tmp_path / "t_seeds.csv"
    bad.write_text("suite,game,agent,seed\npaper,standard,proposed-temporal,0\n")
    done = ncbot("table", str(bad), "--out", str(tmp_path / "t.md"))
    assert done.returncode == 2 and done.stderr.startswith("ncbot: error:") and "lacks a column" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    header = "suite,game,agent,seed,run_id,frames,first.task_success,second.task_success\n"
    bad.write_text(header + "paper,standard,proposed-temporal,0,x,12,high,0.9\n")
    done = ncbot("table", str(bad), "--out", str(tmp_path / "t.md"))
    assert done.returncode == 2 and "line 2, column first.task_success: 'high' is not a number" in done.stderr
