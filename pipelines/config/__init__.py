"""Typed run configuration: the sections (`ncbot.pipelines.config.sections`, every hyper-parameter named and documented
in one place), loading YAML with `key=value` overrides (`ncbot.pipelines.config.files`) and one-line errors for bad values
(`ncbot.pipelines.config.errors`). Importing it stays light: pydantic and yaml, no torch."""
from ncbot.pipelines.config.files import apply_overrides, config_from_dict, dump_config, load_config, parse_override, shipped_config, shipped_configs
from ncbot.pipelines.config.sections import *  # noqa: F401,F403  (every section and limit, as `ncbot.pipelines.config.X`)
from ncbot.pipelines.config.sections import RunConfig

__all__ = ["RunConfig", "apply_overrides", "config_from_dict", "dump_config", "load_config", "parse_override",
           "shipped_config", "shipped_configs"]
