"""ncbot: grids of training runs (`ncbot ablate`, `ncbot reproduce`) on this machine, a Ray cluster or Slurm.

plan.py plans the runs of a grid file; runner.py runs them on a backend (local_backend.py, ray_backend.py,
slurm_backend.py), each try through attempt.py (its `ncbot train` tied to the try's process by tether.py), retrying
tries that died; attempts.py keeps each run's tries in its folder and status.py reads a grid's state from the runs
folder alone.
"""
