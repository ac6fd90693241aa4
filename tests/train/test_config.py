"""Config validation: every shipped YAML loads; unknown keys or wrong types exit 2 with one line naming the key."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from ncbot.pipelines.config import apply_overrides, config_from_dict, dump_config, load_config

CONFIGS = Path(__file__).resolve().parents[2] / "pipelines" / "configs"


RUN_CONFIGS = [CONFIGS / "default.yaml", CONFIGS / "ultimate.yaml", CONFIGS / "ultimate_threats.yaml",
               *sorted((CONFIGS / "paper").glob("*.yaml"))]


@pytest.mark.parametrize("path", RUN_CONFIGS, ids=lambda p: p.name)
def test_every_shipped_run_config_is_valid(path: Path) -> None:
    config = load_config(path)
    assert config.agent.name in ("dqn_original", "dqn_variant", "proposed")


def test_paper_configs_carry_the_paper_hyper_parameters() -> None:
    papers = sorted((CONFIGS / "paper").glob("*.yaml"))
    assert len(papers) == 12
    for path in papers:
        config = load_config(path)
        assert (config.buffer.size, config.buffer.batch_size) == (10_000, 2)
        assert config.collector.init_random_frames == 1_000
        assert config.loss.gamma == 0.7 and config.collector.eps_end == 0.005
        assert config.collector.total_frames == 400_000
        assert config.agent.hidden in ([100] * 3, [150] * 3)


def test_overrides_set_nested_keys_with_yaml_types(tmp_path: Path) -> None:
    config = load_config(CONFIGS / "default.yaml", ["optim.lr=5e-4", "agent.hidden=[64, 64]", "env.temporal=false"])
    assert config.optim.lr == 5e-4 and config.agent.hidden == [64, 64] and config.env.temporal is False
    # the resolved config round-trips through YAML
    saved = tmp_path / "config.yaml"
    saved.write_text(dump_config(config))
    assert load_config(saved) == config


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"optim": {"learning_rate": 1}}, "unknown config key 'optim.learning_rate'; allowed: lr"),
        ({"optimizer": {}}, "unknown config key 'optimizer'"),
        ({"optim": {"lr": "fast"}}, "'optim.lr' must be a number"),
        ({"env": {"batch_size": 1.5}}, "'env.batch_size' must be an integer"),
        ({"env": {"temporal": "yes"}}, "'env.temporal' must be true/false"),
        ({"agent": {"name": "dqn"}}, "'agent.name' must be one of 'dqn_original'"),
        ({"agent": {"hidden": [100, "x"]}}, "'agent.hidden[1]' must be an integer"),
        ({"loss": {"gamma": 1.5}}, "'loss.gamma' must be between 0 and 1"),
        ({"buffer": {"size": 0}}, "'buffer.size' must be > 0 and <= 10000000"),
        ({"env": 3}, "section 'env' must be a mapping"),
        ({"env": {"first": "me"}}, "'env.first' must be one of 'robot', 'human', 'alternate', 'random', got 'me'"),
        ({"env": {"batch_size": "3"}}, "'env.batch_size' must be an integer > 0 and <= 65536, got '3'"),
        ({"train": {"episodes": 0}}, "'train.episodes' must be > 0 and <= 1000000000, got 0"),
        ({"train": {"episodes": 2.5}}, "'train.episodes' must be an integer > 0 and <= 1000000000 or null, got 2.5"),
        ({"agent": {"hidden": []}}, "'agent.hidden' must be a non-empty list"),
        ({"selfplay": {"random_share": 2}}, "'selfplay.random_share' must be between 0 and 1, got 2"),
        ({"schedule": {"lr_end": 0.1}}, "'schedule.lr_end' must be > 0 and <= optim.lr (0.001), got 0.1"),
        ({"logger": {"backend": "tb"}}, "'logger.backend' must be one of 'csv', 'tensorboard', 'wandb', 'mlflow', 'none'"),
        ({"collector": {"init_random_frames": -1}}, "'collector.init_random_frames' must be between 0 and 10000000000, got -1"),
    ],
)
def test_bad_values_give_one_line_naming_the_key(data: dict, message: str) -> None:
    with pytest.raises(ValueError) as error:
        config_from_dict(data)
    assert message in str(error.value) and "\n" not in str(error.value)


def test_override_without_equals_is_rejected() -> None:
    with pytest.raises(ValueError, match="section.key=value"):
        apply_overrides({}, ["optim.lr"])


def _ncbot(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ncbot", *args], capture_output=True, text=True, cwd=cwd)


def test_cli_exits_2_with_one_line_for_unknown_key_and_wrong_type(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("optim:\n  lr: 0.001\n  momentum: 0.9\n")
    result = _ncbot("train", str(bad), "--out", str(tmp_path / "run"), cwd=tmp_path)
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        "ncbot: error: unknown config key 'optim.momentum'; allowed: lr, updates_per_batch, max_grad_norm, weight_decay, precision"
    ]
    result = _ncbot("train", str(CONFIGS / "default.yaml"), "buffer.batch_size=big", cwd=tmp_path)
    assert result.returncode == 2
    assert len(result.stderr.strip().splitlines()) == 1 and "'buffer.batch_size' must be an integer" in result.stderr
    result = _ncbot("train", str(tmp_path / "missing.yaml"), cwd=tmp_path)
    assert result.returncode == 2 and "not found" in result.stderr and "Traceback" not in result.stderr
    assert not (tmp_path / "run").exists()


def test_importing_the_config_does_not_import_torch() -> None:
    """The CLI and tools read configs without paying the ~3 s of importing torch."""
    code = "import ncbot.pipelines.config, sys; assert 'torch' not in sys.modules, 'torch was imported'"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


def test_who_opens_the_test_games_is_eval_first_only() -> None:
    """`eval.first: robot|human|alternate` is the one key; `eval.seat` is refused like any unknown key."""
    assert config_from_dict({"eval": {"first": "human"}}).eval.first == "human"
    with pytest.raises(ValueError, match="seat"):
        config_from_dict({"eval": {"seat": "first"}})


def test_numbers_from_yaml_and_plain_dicts_for_checkpoints(tmp_path: Path) -> None:
    """5e-4 (a YAML 1.1 string) is a number; to_dict() is plain data that YAML and torch.save store."""
    config = load_config(CONFIGS / "default.yaml", ["optim.lr=5e-4", "loss.loss_reward=-20"])
    assert config.optim.lr == 5e-4 and isinstance(config.loss.loss_reward, float)
    data = config.to_dict()
    assert data["selfplay"]["pool_size"] == 5 and data["logger"]["backend"] == "csv"
    assert config_from_dict(data) == config
    assert dump_config(config).startswith("env:\n  game: standard\n")


def test_ultimate_threats_is_ultimate_plus_the_threat_planes_only() -> None:
    base, threats = load_config(CONFIGS / "ultimate.yaml").to_dict(), load_config(CONFIGS / "ultimate_threats.yaml").to_dict()
    assert threats["env"].pop("options") == {"threat_features": True} and base["env"].pop("options") == {}
    assert threats == base
