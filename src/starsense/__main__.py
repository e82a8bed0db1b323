"""``python -m starsense``: the command line, the same as the ``starsense`` script."""

from starsense.cli import _console_main

if __name__ == "__main__":
    raise SystemExit(_console_main())
