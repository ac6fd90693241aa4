"""`ncbot robot ...`: the simulated Pepper (SAPIEN) — play whole games, render the mouth camera, write the URDF.

The logic lives in `robot_sim`; this module parses options, builds the policy (a trained checkpoint through
`ncbot.pipelines.agents.load_agent`, or the look-ahead filter alone), and prints results. SAPIEN, torch and cv2 are
imported inside the commands so `ncbot --help` stays fast.
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ncbot.pipelines.cli.conventions import (json_option, no_progress_option, out_file, out_folder, print_json,
                                             progress_alias, wrote)
from ncbot.pipelines.extras import require
from ncbot.pipelines.outputs import check_writable_dir, check_writable_file

MAX_PIXELS = 4096  # camera width/height bound: a 4K frame; 100000 x 100000 would need 30 GB (docs/reliability.md)

robot_app = typer.Typer(help="The simulated Pepper robot (SAPIEN): play games, render the mouth camera.",
                        no_args_is_help=True)


IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp")  # what cv2.imwrite can encode


def check_meshes(meshes: Optional[Path]) -> None:
    """--meshes must be a folder holding at least one mesh file (an empty one silently drew primitives)."""
    if meshes is None:
        return
    if not meshes.is_dir():
        raise FileNotFoundError(f"meshes folder {meshes} does not exist; expected a folder of <Link>.dae/.stl/.obj files")
    if not any(p.suffix.lower() in (".dae", ".stl", ".obj") for p in meshes.iterdir()):
        raise ValueError(f"meshes folder {meshes} holds no .dae/.stl/.obj file; expected meshes named after the links")


def check_learning(learn: bool, out: Optional[Path], person: str, wrong_claims: float, weights: Optional[Path]) -> None:
    """--learn's needs (a log folder, a person's name that makes a folder name), the share and the weights: one line."""
    import re

    if learn and out is None:
        raise ValueError("--learn needs --out DIR: each game is learned from its MCAP log, and the learning is kept there")
    if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}", person):
        raise ValueError(f"--person must be a name of letters, digits, '_', '.', '-' (at most 64); got {person!r}")
    if not 0.0 <= wrong_claims <= 1.0:
        raise ValueError(f"--wrong-claims must be a share in [0, 1]; got {wrong_claims}")
    if weights is not None:
        from ncbot.vision.classifier import load_classifier

        load_classifier(weights)  # missing, not a torch file, not a CellCNN's: one line now


def _simulator_unavailable(error: Exception) -> None:
    typer.echo(f"ncbot: error: {error}", err=True)
    raise typer.Exit(2)


CHECKPOINT_HELP = ("A checkpoint .pt written by ncbot train, or its run folder (its game is played); without it the "
                   "look-ahead filter alone plays.")
GAME_HELP = ("standard (3x3), ultimate (9x9), a declared game (a shipped name such as four or connect_four, or a "
             "YAML file) or a game class (my_pkg.games:Misere, path/to/file.py:Misere); a checkpoint plays its own "
             "game, so with one this only checks it (and names the game class of a run of your own game).")


def game_and_agent(checkpoint: Optional[Path], game: Optional[str]):
    """(game, checkpoint file or None, (config, policy) or None): the game is the checkpoint's where one is given."""
    from ncbot.envs.games import load_game
    from ncbot.robot_sim.scene import check_game

    if checkpoint is None:
        game = load_game(game or "standard").id  # a file becomes its absolute path, like a run's config
        check_game(game)
        return game, None, None
    from ncbot.pipelines.agents import load_agent
    from ncbot.pipelines.checkpoint import FINAL_NAME

    if game is not None:
        game = load_game(game).id  # a bad name: one line before the checkpoint is loaded
    agent = load_agent(checkpoint)  # a missing file, a run folder without checkpoint.pt, a foreign file: one line
    trained = agent[0].env.game
    if game is not None and game != trained:
        raise ValueError(f"--game {game} does not match the checkpoint, which plays {trained}; drop --game")
    return trained, checkpoint / FINAL_NAME if checkpoint.is_dir() else checkpoint, agent


@robot_app.command("play")
def play(
    checkpoint: Optional[Path] = typer.Argument(None, help=CHECKPOINT_HELP),
    game: Optional[str] = typer.Option(None, help=GAME_HELP),
    games: int = typer.Option(1, help="Games to play (1 to 10000)."),
    seed: int = typer.Option(0, help="Seed of the env, the simulated human and the robot's marks."),
    out: Optional[Path] = out_folder(None, "the MCAP log, PNG snapshots and report.json (none by default)."),
    rrd: bool = typer.Option(False, help="Also export the run to OUT/run.rrd (rerun)."),
    first: str = typer.Option("robot", "--first", help="Who opens: robot, human, alternate, random."),
    opponent: str = typer.Option("random", help="The simulated human's opponent model (random, rule, minimax, mcts:N)."),
    width: int = typer.Option(640, min=16, max=MAX_PIXELS, help="Mouth camera width (pixels)."),
    height: int = typer.Option(480, min=16, max=MAX_PIXELS, help="Mouth camera height (pixels)."),
    occlusion: bool = typer.Option(True, help="Show the human's arm and hand while drawing."),
    wait_probability: float = typer.Option(0.0, help="Chance that the human waits before drawing."),
    nudge_probability: float = typer.Option(0.0, help="Chance that the sheet is nudged after a human move."),
    robot_frame_period: float = typer.Option(1.0, help="Simulated seconds between logged camera frames while the robot moves."),
    robot_draws: bool = typer.Option(False, help="Ultimate: the robot draws its own marks (default: it points and says, the human draws); in every other game it draws them."),
    audio: bool = typer.Option(False, help="Also write the robot's utterances as OUT/speech/*.wav."),
    speech: str = typer.Option("real", help="real: the robot speaks (espeak-ng), the person answers (flite) over the conditions' noise and the robot hears it through pocketsphinx, audio in the MCAP log; text: nothing spoken or heard (simulated ASR, quicker)."),
    meshes: Optional[Path] = typer.Option(None, help="Folder of licensed Pepper meshes (<Link>.dae) to draw instead of primitives."),
    conditions: str = typer.Option("lab", help="The field's conditions: lab, office, atrium, random, or a YAML file of ranges (docs/robot.md)."),
    no_progress: bool = no_progress_option(),
    _progress: bool = progress_alias(),
    as_json: bool = json_option(),
    weights: Optional[Path] = typer.Option(None, help="Cell classifier weights the robot reads with (ncbot vision train --out W); default: the shipped ones."),
    learn: bool = typer.Option(False, help="Learn from the games as they are played: the reader after each game, the play too with a checkpoint (needs --out; resumes a run in --out)."),
    person: str = typer.Option("person", help="Whose learning this is (--learn): its state lives in OUT/learning/PERSON."),
    learn_every: int = typer.Option(1, min=1, help="Update the reader after every N games (--learn)."),
    wrong_claims: float = typer.Option(0.0, help="Share of the simulated person's moves they claim in another cell when a game is settled (wrong labels for --learn)."),
    ears: str = typer.Option("array", help="Real speech: array = Pepper's four head microphones in the game's room (then --enhancement); mono = one microphone, the noise mixed into the reply."),
    enhancement: str = typer.Option("mvdr+vad", help="The array's enhancement: none|ds|mvdr [+vad] [+postfilter] [+doa] (docs/speech.md)."),
    answers: str = typer.Option("confidence", help="A cell said aloud after an unseen move: confidence = accept, confirm or ask for a touch on the tablet by the recogniser's confidence; confirm = confirm every cell, ask up to 3 times."),
) -> None:
    """Play whole games: the robot sees only rendered frames and hears only the dialogue; prints what happened."""
    from ncbot.pipelines.run_env import check_first

    check_first(first, ("robot", "human", "alternate", "random"), "--first")
    if not 1 <= games <= 10_000:
        raise ValueError(f"--games must be a number of games from 1 to 10000, got {games}")
    if out is None and rrd:
        raise ValueError("--rrd needs --out DIR (the recording is exported from the run's MCAP log)")
    check_meshes(meshes)
    if out is not None:
        check_writable_dir(out, "--out")
    if speech not in ("real", "text"):
        raise ValueError(f"--speech must be real or text; got {speech!r}")
    check_learning(learn, out, person, wrong_claims, weights)
    if robot_frame_period <= 0:
        raise ValueError(f"--robot-frame-period must be positive seconds; got {robot_frame_period}")
    if not 0.0 <= wait_probability <= 1.0 or not 0.0 <= nudge_probability <= 1.0:
        raise ValueError("--wait-probability and --nudge-probability must be in [0, 1]")
    require_play_extras(speech, ears, rrd)
    import torch

    from ncbot.robot_sim.human import HumanConfig
    from ncbot.robot_sim.play import RobotPlayConfig, play_robot_games
    from ncbot.pipelines.progress import progress_bar
    from ncbot.robot_sim.render_system import SimulatorUnavailable

    torch.set_num_threads(1)
    game, checkpoint, agent = game_and_agent(checkpoint, game)
    policy, agent_name = None, "lookahead"
    if agent is not None:
        agent_config, policy = agent
        agent_name = f"{agent_config.agent.name}:{checkpoint}"
    config = RobotPlayConfig(
        game=game, games=games, seed=seed, first=first, camera_width=width, camera_height=height,
        human=HumanConfig(opponent=opponent, show_arm=occlusion, wait_probability=wait_probability,
                          nudge_probability=nudge_probability, wrong_claims=wrong_claims),
        ultimate_robot_draws=robot_draws, audio=audio, agent_name=agent_name, robot_frame_period=robot_frame_period,
        meshes_dir=None if meshes is None else str(meshes), conditions=conditions, speech=speech, ears=ears,
        enhancement=enhancement, answers=answers, weights=None if weights is None else str(weights))
    config.validate()
    bar = None if no_progress else progress_bar
    try:
        if learn:
            from ncbot.pipelines.online.learning import LearnSettings
            from ncbot.pipelines.online.robot_games import play_and_learn

            settings = LearnSettings.default(checkpoint, learn_every, seed)
            report = play_and_learn(config, checkpoint, out, person, settings, bar)
        else:
            with torch.no_grad():
                report = play_robot_games(config, policy, out_dir=out, progress=bar)
    except SimulatorUnavailable as error:
        _simulator_unavailable(error)
    if rrd and out is not None:
        from ncbot.logs.rerun_export import export_to_rerun

        export_to_rerun(out, out / "run.rrd")
        report["rrd"] = str(out / "run.rrd")
    if as_json:
        print_json({**report, **({"written": [str(out)]} if out is not None else {})})
    else:
        typer.echo(games_text(report))
    if out is not None:
        wrote(f"the games' MCAP log, snapshots and report.json to {out}" + (" and the rerun recording run.rrd" if rrd else ""))


def require_play_extras(speech: str, ears: str, rrd: bool) -> None:
    """One line naming the extra to install, before anything heavy loads, for what this `robot play` needs."""
    require("robot", "sapien", what="ncbot robot play")
    if speech == "real":
        require("speech", "pocketsphinx", what="ncbot robot play --speech real")
        if ears == "array":
            require("speech", "pyroomacoustics", "webrtcvad", what="ncbot robot play --ears array")
    if rrd:
        require("rerun", "rerun", what="ncbot robot play --rrd")


def games_text(report: dict) -> str:
    """`robot play`'s headline in a few lines (--json gives every figure)."""
    turn = report["seconds_per_robot_turn"]
    lines = [f"{report['games']} game{'s' if report['games'] != 1 else ''} of {report['game']} ({report['agent']}, conditions "
             f"{report['conditions']}): {report['wins']} won, {report['draws']} drawn, {report['losses']} lost, "
             f"{report['unfinished']} unfinished",
             f"moves: {report['human_moves']} by the person, {report['misrecognised_moves']} misrecognised and "
             f"{report['unseen_moves']} unseen; {report['robot_moves']} by the robot"
             + (f", {turn:.2f} s a turn" if turn is not None else "")]
    if report["speech"] == "real" and report["asr_word_error_rate"] is not None:
        lines.append(f"speech: word error rate {report['asr_word_error_rate']:.3f} over {report['asr_utterances']} "
                     f"replies heard")
    return "\n".join(lines)


@robot_app.command("serve")
def serve(
    checkpoint: Optional[Path] = typer.Argument(None, help=CHECKPOINT_HELP),
    game: Optional[str] = typer.Option(None, help=GAME_HELP),
    host: str = typer.Option("127.0.0.1", help="Address to listen on (loopback by default; a study on a LAN needs 0.0.0.0)."),
    port: int = typer.Option(8000, min=1, max=65535, help="TCP port."),
    out: Path = out_folder(Path("runs/study"), "the sessions' MCAP logs (one session-<id>/ each)."),
    width: int = typer.Option(320, help="Mouth camera width (pixels)."),
    height: int = typer.Option(240, help="Mouth camera height (pixels)."),
    idle_seconds: float = typer.Option(300.0, help="Close a session (and finish its log) after this long without a message."),
    max_sessions: int = typer.Option(8, min=1, help="Sessions at once; more get a 'server full' error."),
    audio: bool = typer.Option(True, help="Speak the robot's utterances as WAV (speech.tts) when an engine is installed."),
    seed: int = typer.Option(0, help="Seed of the look-ahead policy, the robot's marks and the conditions."),
    conditions: str = typer.Option("lab", help="The field's conditions: lab, office, atrium, random, or a YAML file of ranges (docs/robot.md)."),
    answer_seconds: float = typer.Option(30.0, help="Seconds the robot waits for the person's answer before it hears silence."),
    parallel: bool = typer.Option(True, help="Sessions render at once (--no-parallel: one simulator lock for all)."),
    weights: Optional[Path] = typer.Option(None, help="Cell classifier weights the robot reads with; default: the shipped ones."),
    learn: bool = typer.Option(False, help="Learn from each person's games (the reader; the play too with a checkpoint), kept in OUT/learning/PARTICIPANT and resumed when the participant code comes back."),
    pooled: bool = typer.Option(False, help="With --learn: one learning from everyone's games (OUT/learning/pooled)."),
    moves: str = typer.Option("camera", help="Where the robot learns the person's moves: camera (its chest tablet when the camera misses one) or tablet (every move touched on the tablet)."),
) -> None:
    """Let people play the simulated robot in a browser: open http://HOST:PORT/ in one tab per person."""
    from ncbot.robot_sim.conditions import load_conditions

    load_conditions(conditions)  # a bad preset or file: one line now, not a failed game later
    if answer_seconds <= 0:
        raise ValueError(f"--answer-seconds must be positive; got {answer_seconds}")
    if moves not in ("camera", "tablet"):
        raise ValueError(f"--moves must be camera or tablet; got {moves!r}")
    if idle_seconds <= 0:
        raise ValueError(f"--idle-seconds must be positive; got {idle_seconds}")
    check_writable_dir(out, "--out")
    check_learning(False, out, "person", 0.0, weights)
    if pooled and not learn:
        raise ValueError("--pooled says whose learning --learn keeps; give --learn too")
    require("robot", "sapien", what="ncbot robot serve")
    require("serve", "fastapi", "uvicorn", "websockets", what="ncbot robot serve")
    import torch

    from ncbot.pipelines.serve.app import serve as run_server
    from ncbot.pipelines.serve.session import ServeConfig
    from ncbot.robot_sim.render_system import SimulatorUnavailable

    torch.set_num_threads(1)
    game, checkpoint, _ = game_and_agent(checkpoint, game)  # a checkpoint of either game serves its own game
    config = ServeConfig(game=game, checkpoint=None if checkpoint is None else str(checkpoint), out=str(out),
                         camera_width=width, camera_height=height, idle_seconds=idle_seconds,
                         max_sessions=max_sessions, audio=audio, seed=seed, conditions=conditions,
                         answer_seconds=answer_seconds, parallel=parallel, moves=moves,
                         weights=None if weights is None else str(weights), learn=learn, pooled=pooled)
    def listening() -> None:
        typer.echo(f"ncbot robot serve: http://{host}:{port}/ (game {game}, conditions {conditions}, logs in {out})",
                   err=True)

    try:
        run_server(config, host=host, port=port, on_listening=listening)
    except SimulatorUnavailable as error:
        _simulator_unavailable(error)


@robot_app.command("render")
def render(
    output: Path = out_file(Path("runs/robot/mouth.png"), "the frame (.png, .jpg or .bmp; default runs/robot/mouth.png)."),
    game: str = typer.Option("standard", help="standard, ultimate, a declared game (a shipped name such as four or "
                             "connect_four, or a YAML file) or a game class (path/to/file.py:Misere): its grid on the sheet."),
    width: int = typer.Option(640, min=16, max=MAX_PIXELS, help="Camera width."),
    height: int = typer.Option(480, min=16, max=MAX_PIXELS, help="Camera height."),
    marks: str = typer.Option("", help="Marks to put on the sheet, e.g. 'xb2,oa1,xc3' (mark, then the cell as on the board)."),
    seed: int = typer.Option(0, help="Seed of the hand-drawn marks and of the conditions."),
    frames: int = typer.Option(10, min=1, help="Frames to time after the warm-up."),
    view: str = typer.Option("mouth", help="mouth (the robot's CameraBottom) or overview (third person, for people)."),
    conditions: str = typer.Option("lab", help="The field's conditions: lab, office, atrium, random, or a YAML file of ranges; drawn with --seed."),
    as_json: bool = json_option(),
) -> None:
    """Render one mouth-camera (or overview) frame of the home posture to a PNG and print the render cost."""
    import time

    import cv2
    import numpy as np

    if view not in ("mouth", "overview"):
        raise ValueError(f"--view must be mouth or overview; got {view!r}")
    check_writable_file(output, "--out", IMAGE_SUFFIXES)
    require("robot", "sapien", what="ncbot robot render")
    from ncbot.envs.games import load_game
    from ncbot.robot_sim.conditions import load_conditions
    from ncbot.robot_sim.render_system import SimulatorUnavailable
    from ncbot.robot_sim.reach import check_reach
    from ncbot.robot_sim.scene import PepperScene, SceneConfig, placed_by_hand
    from ncbot.robot_sim.sheet import MARK_OF_PLAYER, MarkSpec

    ranges = load_conditions(conditions)
    rules = load_game(game)
    game = rules.id
    try:
        scene = PepperScene(SceneConfig(game=game, camera_width=width, camera_height=height, conditions=ranges,
                                        conditions_seed=seed))
    except SimulatorUnavailable as error:
        _simulator_unavailable(error)
    if not placed_by_hand(game):  # a declared grid's drawing positions were derived, not placed: check each one
        check_reach(scene, rules.cell_name)
    rng = np.random.default_rng(seed)
    taken: set[int] = set()
    for token in filter(None, (t.strip() for t in marks.split(","))):
        try:
            if token[0].lower() not in MARK_OF_PLAYER:
                raise ValueError
            cell = rules.parse_cell(token[1:])
        except ValueError:
            raise ValueError(f"mark {token!r} is not understood; expected x or o followed by a cell such as "
                             f"{rules.cell_name(rules.size + 1)} (column letter, row number), e.g. xb2") from None
        if cell in taken:
            raise ValueError(f"mark {token!r} puts a second mark on {rules.cell_name(cell)}; expected one mark per cell")
        taken.add(cell)
        scene.canvas.draw(MarkSpec(cell, MARK_OF_PLAYER[token[0].lower()], int(rng.integers(2**31)),
                                    scene.conditions.ink_bgr), 1.0)
    grab = scene.render if view == "mouth" else (lambda: scene.render_overview(width, height))
    frame = grab()
    times = []
    for _ in range(frames):
        scene.step(0.02)
        started = time.perf_counter()
        frame = grab()
        times.append(time.perf_counter() - started)
    output.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(output), frame[:, :, ::-1]):
        raise ValueError(f"could not write {output}; expected a writable path ending in .png")
    rendered = {"output": str(output), "width": width, "height": height,
                "ms_per_frame_median": round(1000 * float(np.median(times)), 2), "conditions": scene.conditions.summary()}
    if as_json:
        print_json({**rendered, "written": [str(output)]})
    else:
        typer.echo(f"{view} view, {width}x{height}, {rendered['ms_per_frame_median']} ms a frame (median of {frames}), "
                   f"conditions {scene.conditions.summary().get('preset', conditions)}")
    wrote(str(output))


@robot_app.command("urdf")
def urdf(
    output: Path = out_file(Path("runs/robot/pepper.urdf"), "the URDF (.urdf; default runs/robot/pepper.urdf: the "
                            "packaged robot_sim/assets/pepper.urdf changes only when named here)."),
    meshes: Optional[Path] = typer.Option(None, help="Folder of licensed Pepper meshes named after the links (<Link>.dae)."),
    as_json: bool = json_option(),
) -> None:
    """Write the primitive Pepper URDF (optionally with licensed meshes swapped in for the primitives)."""
    from ncbot.robot_sim.pepper_model import write_pepper_urdf

    check_writable_file(output, "--out", (".urdf",))
    check_meshes(meshes)
    output.parent.mkdir(parents=True, exist_ok=True)
    path = write_pepper_urdf(output, meshes)
    if as_json:
        print_json({"meshes": None if meshes is None else str(meshes), "written": [str(path)]})
    wrote(str(path))


def register(app: typer.Typer) -> None:
    """Add this area's commands to the root app."""
    app.add_typer(robot_app, name="robot")
