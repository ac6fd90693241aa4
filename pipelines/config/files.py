"""Run configs from files: `key=value` overrides, the shipped configs by name or path, loading and dumping YAML
(the sections themselves: `ncbot.pipelines.config.sections`)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError

from ncbot.envs.games import load_game
from ncbot.fileio.yaml_file import read_yaml
from ncbot.pipelines.config.errors import validation_line
from ncbot.pipelines.config.sections import RunConfig


def parse_override(text: str) -> tuple[list[str], Any]:
    """`section.key=value` -> (["section", "key"], YAML-parsed value)."""
    if "=" not in text:
        raise ValueError(f"override {text!r} must look like section.key=value (e.g. optim.lr=0.0005)")
    key, raw = text.split("=", 1)
    path = [part for part in key.strip().split(".") if part]
    if not path:
        raise ValueError(f"override {text!r} has no key before '='")
    try:
        value = yaml.safe_load(raw) if raw.strip() else None
    except yaml.YAMLError:
        value = raw
    return path, value


def apply_overrides(data: dict[str, Any], overrides: list[str]) -> dict[str, Any]:
    """Set each `section.key=value` in the nested mapping (validation happens when the config is built)."""
    for text in overrides:
        path, value = parse_override(text)
        node = data
        for part in path[:-1]:
            child = node.get(part)
            if child is None:
                child = node[part] = {}
            if not isinstance(child, dict):
                raise ValueError(f"override {text!r}: '{part}' is not a section")
            node = child
        node[path[-1]] = value
    return data


def config_from_dict(data: dict[str, Any]) -> RunConfig:
    """Validate a nested mapping into a RunConfig (one-line ValueError on any problem)."""
    if not isinstance(data, dict):
        raise ValueError(f"config must be a mapping of sections (env, agent, ...), got {data!r}")
    data = {key: {} if value is None else value for key, value in data.items()}  # an empty section means defaults
    try:
        return RunConfig.model_validate(data)
    except ValidationError as error:
        raise ValueError(validation_line(error, RunConfig)) from None


SHIPPED_DIR = Path(__file__).resolve().parents[1] / "configs"


def shipped_configs() -> dict[str, Path]:
    """{name: file} of the configs shipped in the package, named by their path under configs/ without .yaml
    (`default`, `ultimate`, `ablation`, `paper/ultimate100_proposed_temporal`, ...)."""
    return {path.relative_to(SHIPPED_DIR).with_suffix("").as_posix(): path for path in sorted(SHIPPED_DIR.rglob("*.yaml"))}


def shipped_config(path: str | Path) -> Path:
    """`path` when it exists; else the shipped config it names: a name (`default`, `paper/standard_original`) or a
    checkout path (`pipelines/configs/default.yaml`, so the README's commands also work outside a clone).

    A text that looks like a name (no .yaml/.yml suffix) and names neither a file nor a shipped config is a one-line
    ValueError listing the names; a missing file path is left to the reader's own error."""
    path = Path(path)
    if path.exists():
        return path
    parts = path.parts
    if len(parts) > 2 and parts[:2] == ("pipelines", "configs") and SHIPPED_DIR.joinpath(*parts[2:]).is_file():
        return SHIPPED_DIR.joinpath(*parts[2:])
    names = shipped_configs()
    name = path.as_posix().removesuffix(".yaml")
    if name in names:
        return names[name]
    if path.suffix not in (".yaml", ".yml"):
        raise ValueError(f"config {str(path)!r} is neither a file nor a shipped config; shipped: "
                         f"{', '.join(n for n in names if '/' not in n)}, paper/... (ncbot configs lists them)")
    return path


def load_config(path: str | Path, overrides: list[str] | None = None) -> RunConfig:
    """Read a YAML config, apply overrides and validate it."""
    expected = "a YAML file of config sections, e.g. pipelines/configs/default.yaml"
    data = read_yaml(shipped_config(path), "config file", expected)
    if data is None:
        raise ValueError(f"config file {str(path)!r} is empty; expected {expected} (an empty mapping {{}} means "
                         "every default)")
    if not isinstance(data, dict):
        raise ValueError(f"config file {str(path)!r} must hold a mapping of sections (env, agent, ...)")
    if "grid" in data and "suites" in data:
        raise ValueError(f"{str(path)!r} is an ablation grid, not a run config: run ncbot ablate {path}")
    config = config_from_dict(apply_overrides(data, overrides or []))
    load_game(config.env.game, config.env.free_move)  # the user names the game here: a game class is imported now
    return config


def name_games(overrides: list[str]) -> None:
    """Import the game classes an ``env.game=...`` override names (the command line of a resumed run names its
    game again: a run folder's config alone never imports code, docs/games.md)."""
    for text in overrides:
        path, value = parse_override(text)
        if path == ["env", "game"] and isinstance(value, str):
            load_game(value)


def dump_config(config: RunConfig) -> str:
    """The resolved config as YAML (written next to every run)."""
    return yaml.safe_dump(config.to_dict(), sort_keys=False)
