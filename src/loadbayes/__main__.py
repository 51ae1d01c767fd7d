"""``python -m loadbayes``: the same as the ``loadbayes`` command."""

from loadbayes.cli import main

if __name__ == "__main__":
    main(prog_name="loadbayes")
