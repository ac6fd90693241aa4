"""`ncbot env ...`: look inside the dialogue game env (feature and action tables)."""
from __future__ import annotations

import typer

from ncbot.pipelines.cli.conventions import json_option, print_json

env_app = typer.Typer(help="The multimodal dialogue game env: describe its features and actions.", no_args_is_help=True)


def feature_meaning(key: str, game: str) -> str:
    """A one-line meaning of a feature key such as ``robot_move[04]`` or ``word[hello]``."""
    from ncbot.envs.games import make_game

    kind, _, rest = key.partition("[")
    value = rest.rstrip("]")
    if kind in ("robot_move", "human_move", "time"):
        cell = make_game(game).cell_name(int(value))
        if kind == "time":
            return f"order of the move on {cell} / marks on the board (0 if empty; latest = 1)"
        who = "robot's" if kind == "robot_move" else "human's"
        return f"1 if the {who} mark is on {cell}"
    if kind == "command":
        return f"1 if the last robot act issued the '{value}' command"
    return f"'{value}': 1 if the robot just said it, else the ASR confidence if the user did, else 0"


@env_app.command("describe")
def describe(
    game: str = typer.Option("standard", help="standard (3x3), ultimate (9x9), a shipped declared game (four, "
                             "connect_four), a game YAML file or a game class (path/to/file.py:Misere; docs/games.md)"),
    temporal: bool = typer.Option(True, "--temporal/--no-temporal", help="include the temporal features"),
    as_json: bool = json_option(),
) -> None:
    """Print the feature table (index, key, meaning) and the action table (index, act, template, command)."""
    from ncbot.envs import make_env
    from ncbot.envs.games import load_game
    from ncbot.logs.names import NameTables

    rules = load_game(game)
    game = rules.id
    env = make_env(game, temporal=temporal)
    names = NameTables.from_env(env)  # acts as people read them: GameMove(b2), Provide(feedback=lose)
    features = [{"index": index, "key": key, "meaning": feature_meaning(key, game)}
                for index, key in enumerate(env.feature_names)]
    actions = []
    for index in range(len(env.action_names)):
        template, _, command = env.describe_action(index).partition(" [")
        actions.append({"index": index, "act": names.action_name(index), "template": template,
                        "command": command.removesuffix("]")})
    if as_json:
        print_json({"game": rules.name, "features": features, "actions": actions, "words": list(env.words)})
        return
    typer.echo(rules.describe())
    typer.echo(f"{rules.name} game: {env.n_features} features, {env.n_actions} actions, vocabulary of {len(env.words)} words\n")
    typer.echo("FEATURES (the sorted key-value memory as a vector)")
    typer.echo(f"{'index':>5}  {'key':<18} meaning")
    for feature in features:
        typer.echo(f"{feature['index']:>5}  {feature['key']:<18} {feature['meaning']}")
    typer.echo("\nACTIONS (dialogue acts)")
    typer.echo(f"{'index':>5}  {'dialogue act':<26} {'template':<40} command")
    for action in actions:
        typer.echo(f"{action['index']:>5}  {action['act']:<26} {action['template']:<40} [{action['command']}]")


def register(app: typer.Typer) -> None:
    """Add this area's commands to the root app."""
    app.add_typer(env_app, name="env")
