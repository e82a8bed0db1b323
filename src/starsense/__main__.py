"""``python -m starsense``: the command line, the same as the ``starsense`` script."""

from starsense.cli import console_main

if __name__ == "__main__":
    raise SystemExit(console_main())
