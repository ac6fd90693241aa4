"""`python -m ncbot ...`: the same as the `ncbot` console script."""
from ncbot.pipelines.cli.app import main

if __name__ == "__main__":
    main()
