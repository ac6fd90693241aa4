"""ncbot logs: every episode (training, evaluation, robot simulator) to MCAP, and reading it back.

Writing (the training pipeline and the robot simulator)::

    from ncbot.logs import EpisodeLogger
    with EpisodeLogger(run_dir, run_info={"config": cfg}) as log:      # run_dir/episodes-0000.mcap, ...
        log.record_steps(td, phase="train", agent="proposed", seed=0, epsilon=0.1, env_steps=12345, env=env)
        log.log_camera(jpeg_bytes, t=sim_time)                          # robot simulator extras
        log.log_joint_states(names, positions, t=sim_time)
        log.log_transform("world", "base_link", (x, y, 0.0), (0, 0, qz, qw), t=sim_time)

Reading: `read_episodes(path)` (summaries), `read_episode_records(path, ids)` (steps, dialogue, boards),
`LogReader(path)` (any message, with crash recovery: `scans[file].cut_bytes`), `summarize(path)` (what
`ncbot logs inspect --json` prints, in `ncbot.logs.summary`). Channels and their schemas are in `ncbot.logs.schemas` and
`ncbot.logs.packed`; why the formats are what they are, with measurements, is in `logs/README.md`.
"""
from ncbot.logs.reader import EpisodeRecord, FileScan, LogMessage, LogReader, read_episode_records, read_episodes
from ncbot.logs.schemas import OUTCOMES, PHASES
from ncbot.logs.writer import EpisodeLogger

__all__ = ["EpisodeLogger", "LogReader", "LogMessage", "FileScan", "EpisodeRecord", "read_episodes",
           "read_episode_records", "OUTCOMES", "PHASES"]
