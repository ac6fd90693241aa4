"""`python -m ncbot.pipelines.cli ...`: the same as `python -m ncbot` and the `ncbot` console script."""
from ncbot.pipelines.cli.app import main

if __name__ == "__main__":
    main()
