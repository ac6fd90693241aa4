"""Training: one run (`run`), self-play, the value net, ablations and the Ray backend that runs many."""
