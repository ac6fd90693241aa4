"""`python -m pipelines.cli ...`: the same as the `ncbot` console script."""
from pipelines.cli.app import main

if __name__ == "__main__":
    main()
