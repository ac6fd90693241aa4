"""`ncbot train pipelines/configs/default.yaml` outside a clone (a wheel install) reads the shipped config."""
from __future__ import annotations

from pathlib import Path

import pytest

from ncbot.pipelines.config import load_config, shipped_config

SHIPPED = Path(__file__).resolve().parents[2] / "pipelines" / "configs"


def test_a_missing_configs_path_falls_back_to_the_shipped_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no pipelines/ folder here
    assert shipped_config("pipelines/configs/default.yaml") == SHIPPED / "default.yaml"
    assert shipped_config("pipelines/configs/paper/standard_proposed_temporal.yaml").is_file()
    assert load_config("pipelines/configs/default.yaml").agent.name == "proposed"


def test_a_local_file_wins_and_other_missing_paths_stay_errors(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    local = tmp_path / "pipelines" / "configs" / "default.yaml"
    local.parent.mkdir(parents=True)
    local.write_text("agent: {name: dqn_variant}\n")
    assert shipped_config("pipelines/configs/default.yaml") == Path("pipelines/configs/default.yaml")
    assert load_config("pipelines/configs/default.yaml").agent.name == "dqn_variant"
    with pytest.raises(FileNotFoundError, match="nosuch.yaml"):
        load_config("pipelines/configs/nosuch.yaml")
    with pytest.raises(FileNotFoundError):
        load_config("default.yaml")
