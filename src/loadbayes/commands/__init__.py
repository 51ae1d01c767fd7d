"""The CLI commands, one module per subject; :mod:`loadbayes.cli` gathers them."""
