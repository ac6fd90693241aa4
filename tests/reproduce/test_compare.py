"""`ncbot compare RUN... --against RUN...`: two sets of finished runs over seeds (pipelines/reproduce/compare.py)."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

from matplotlib.image import imread
import pytest
from scipy.stats import mannwhitneyu, ttest_ind

from ncbot.pipelines.reproduce.compare import compare
from ncbot.pipelines.reproduce.two_sample import welch_difference
from tests.learning_helpers import ncbot

AHEAD = [0.951, 0.933, 0.947, 0.940, 0.929, 0.956]
PAPER_MODE = [0.926, 0.877, 0.931, 0.904, 0.949, 0.902, 0.896, 0.918, 0.910, 0.898]


def cell(root: Path, values: list[float], length: float = 60.0) -> Path:
    """A grid cell as `ncbot ablate` writes it: seedN/eval.json, one per run, each with its own run id."""
    for seed, value in enumerate(values):
        folder = root / f"seed{seed}"
        folder.mkdir(parents=True)
        (folder / "eval.json").write_text(json.dumps({
            "run_id": f"{root.name}-{seed}", "frames": 400000,
            "first": {"games": 3000, "task_success": value, "win": value - 0.2, "avg_length": length + seed},
            "second": {"games": 3000, "task_success": value - 0.03}}))
    return root


def test_the_numbers_are_scipys(tmp_path: Path) -> None:
    ahead, paper = cell(tmp_path / "ahead", AHEAD), cell(tmp_path / "paper", PAPER_MODE)
    found = compare([str(ahead)], [str(paper)], effect=0.031)
    t, df, p = found.test.welch
    reference = ttest_ind(AHEAD, PAPER_MODE, equal_var=False, alternative="greater")
    assert t == pytest.approx(reference.statistic) and p == pytest.approx(reference.pvalue)
    assert found.test.rank_p == pytest.approx(mannwhitneyu(AHEAD, PAPER_MODE, alternative="greater").pvalue)
    assert found.difference.mean == pytest.approx(sum(AHEAD) / 6 - sum(PAPER_MODE) / 10)
    assert found.difference.low < found.difference.mean < found.difference.high
    assert 0.5 < found.test.improvement[0] <= 1 and found.test.improvement[1] <= found.test.improvement[0] <= found.test.improvement[2]
    assert 0 < found.power < 1 and found.verdict.startswith("RUN higher at alpha 0.05")
    # the same runs named one by one: the same comparison
    one_by_one = compare([str(p) for p in sorted(ahead.iterdir())], [str(paper)])
    assert one_by_one.test.welch == found.test.welch


def test_power_decides_between_untested_and_not_shown(tmp_path: Path) -> None:
    near = cell(tmp_path / "near", [0.930, 0.880, 0.925])  # level with paper mode, spread wider
    paper = cell(tmp_path / "paper", PAPER_MODE)
    weak = compare([str(near)], [str(paper)], effect=0.031)
    assert weak.test.welch[2] > 0.05 and weak.power < 0.8 and weak.verdict.startswith("untested: power")
    strong = compare([str(near)], [str(paper)], effect=0.2)
    assert strong.power > 0.8 and strong.verdict.startswith("not shown")
    behind = compare([str(paper)], [str(cell(tmp_path / "high", [0.97, 0.96, 0.98]))], effect=0.2)
    assert behind.verdict == "no: RUN did not come out higher"


def test_less_tests_a_metric_where_lower_is_better(tmp_path: Path) -> None:
    short = cell(tmp_path / "short", AHEAD, length=30.0)
    long = cell(tmp_path / "long", PAPER_MODE, length=60.0)
    found = compare([str(short)], [str(long)], metric="first.avg_length", larger=False)
    shorter = [30.0 + seed for seed in range(6)]
    longer = [60.0 + seed for seed in range(10)]
    assert found.test.welch[2] == pytest.approx(ttest_ind(shorter, longer, equal_var=False, alternative="less").pvalue)
    assert found.difference.mean == pytest.approx(sum(shorter) / 6 - sum(longer) / 10)
    direct = welch_difference(shorter, longer)  # the interval on the metric's own sign, not the test's negated one
    assert (found.difference.low, found.difference.high) == pytest.approx((direct.low, direct.high))
    assert found.verdict.startswith("RUN lower")


def test_cli_prints_writes_and_speaks_json(tmp_path: Path) -> None:
    ahead, paper = cell(tmp_path / "ahead", AHEAD), cell(tmp_path / "paper", PAPER_MODE)
    out = tmp_path / "report.md"
    done = ncbot("compare", str(ahead), "--against", str(paper), "--effect", "0.031", "--out", str(out))
    assert done.returncode == 0, done.stderr
    assert "| RUN | 6 |" in done.stdout and "| --against | 10 |" in done.stdout
    assert out.read_text() + "\n" == done.stdout  # the file holds what was printed
    figure = imread(tmp_path / "report.png")  # every run drawn beside it, named in the report
    assert figure.ndim == 3 and figure.shape[0] > 100 and figure.std() > 0 and "[report.png](report.png)" in done.stdout
    as_json = json.loads(ncbot("compare", str(ahead), "--against", str(paper), "--json").stdout)
    assert as_json["p"] < 0.05 and len(as_json["runs"]) == 6 and len(as_json["against"]) == 10


@pytest.mark.parametrize("case, expected", [
    ("copy", "are the same run"),
    ("both", "are the same run"),
    ("one", "needs at least 2 finished runs"),
    ("missing", "is neither a finished run folder"),
    ("metric", "--metric 'first.nosuch' is not in"),
    ("effect", "--effect is the size of the difference"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path: Path, case: str, expected: str) -> None:
    ahead, paper = cell(tmp_path / "ahead", AHEAD), cell(tmp_path / "paper", PAPER_MODE)
    args = {"copy": [str(ahead), "--against", str(paper)],
            "both": [str(ahead), "--against", str(ahead / "seed0"), "--against", str(paper)],
            "one": [str(ahead / "seed0"), "--against", str(paper)],
            "missing": [str(tmp_path / "nowhere"), "--against", str(paper)],
            "metric": [str(ahead), "--against", str(paper), "--metric", "first.nosuch"],
            "effect": [str(ahead), "--against", str(paper), "--effect", "-0.1"]}[case]
    if case == "copy":
        shutil.copytree(ahead / "seed0", paper / "seed99")  # a copied seed folder keeps its run id
    done = ncbot("compare", *args)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and expected in done.stderr and "Traceback" not in done.stderr
