"""`ncbot reproduce ... --backend ray` on a local Ray instance at a toy budget: every run's folder ends up under the
head's runs folder, finished runs are skipped, and a node that cannot see the runs folder is one clear error.

Ray is an optional extra (`pip install 'ncbot[ray]'`): without it these tests are skipped, not failed.
"""
from __future__ import annotations

from pathlib import Path

import pytest

from ncbot.pipelines.grid.plan import PlannedRun
from ncbot.pipelines.grid.runner import Cluster, execute_runs
from ncbot.pipelines.reproduce.grid import Budget, reproduce
from tests.learning_helpers import write_paper_configs

ray = pytest.importorskip("ray", reason="ray is an optional extra (pip install 'ncbot[ray]'); not installed here")

TOY = Budget(name="toy", seeds=1, rows=("standard",), max_games={"standard": 4}, eval_games=10,
             eval_every_frames={"standard": 64}, game_points=(2,), label="TOY BUDGET (ray test)")


def test_reproduce_table_on_a_local_ray_instance_puts_every_run_under_the_runs_folder(tmp_path: Path) -> None:
    configs = write_paper_configs(tmp_path, 128)
    runs, out = tmp_path / "runs", tmp_path / "results"
    result = reproduce("table", TOY, out=out, runs=runs, cluster=Cluster("ray", workers=2), configs=configs)
    # 5 cells a row: the uniform choice inside the masks, the three agents, Proposed with temporal features
    assert (result["runs"]["done"], result["runs"]["failed"]) == (5, 0), result["runs"]
    finished = sorted(p.relative_to(runs) for p in runs.glob("toy/paper/standard/*/seed0/eval.json"))
    assert len(finished) == 5 and (out / "paper_table.md").is_file()
    assert not list(runs.rglob(".ncbot-ray-probe-*"))  # the shared-folder marker is removed after the check
    again = reproduce("table", TOY, out=out, runs=runs, cluster=Cluster("ray", workers=2), configs=configs)
    assert (again["runs"]["done"], again["runs"]["skipped"]) == (0, 5)


def test_a_runs_folder_the_nodes_cannot_see_is_one_clear_error(tmp_path: Path) -> None:
    from ncbot.pipelines.grid.ray_backend import _probe

    where, problem = _probe(str(tmp_path / "not-shared" / ".ncbot-ray-probe-x"))
    assert where and "is not shared with node" in problem and "same absolute path on every node" in problem
    assert _probe(__file__) == (where, "")  # a visible file on a node that imports ncbot: no problem


def test_address_without_ray_backend_and_runs_outside_the_folder_are_refused(tmp_path: Path) -> None:
    run = PlannedRun("x", tmp_path / "elsewhere" / "seed0", tmp_path / "c.yaml")
    with pytest.raises(ValueError, match="--address 1.2.3.4:6379 needs --backend ray"):
        execute_runs([run], cluster=Cluster("local", workers=1, address="1.2.3.4:6379"))
    with pytest.raises(ValueError, match="is not under the runs folder"):
        execute_runs([run], cluster=Cluster("ray", workers=1), runs_dir=tmp_path / "runs")
