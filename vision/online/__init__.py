"""The reader that learns from play: cells the games settled become labelled examples, and the cell classifier is
updated from them between games (with rehearsal of its own training cells, kept only if not worse on a held-back
check set). `ncbot.robot_sim.settlement` collects a game's views; `ncbot.pipelines.online` runs the updates for
`ncbot robot play --learn`, `ncbot robot serve --learn` and `ncbot learn`."""
from ncbot.vision.online.adapt import ReaderLearner, ReaderLearning, ReaderUpdate
from ncbot.vision.online.examples import CellExamples, View, settled_examples

__all__ = ["CellExamples", "ReaderLearner", "ReaderLearning", "ReaderUpdate", "View", "settled_examples"]
