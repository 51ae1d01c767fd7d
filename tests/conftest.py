"""Test-wide settings.

The fit entry points issue a fit's warnings as :class:`loadbayes.posterior.FitWarning`
as well as keeping them in ``post.warnings``. Under ``filterwarnings = error`` every test
of degenerate data would stop at the warning instead of checking ``post.warnings``, which
is what those tests assert on; so FitWarning is ignored here, and the warning channel
itself is tested with ``pytest.warns`` (which records whatever the filters say) in
``tests/unit/test_api.py``. Every other warning still fails a test.
"""

import pytest


def pytest_collection_modifyitems(items):  # noqa: D103
    for item in items:
        item.add_marker(pytest.mark.filterwarnings("ignore::loadbayes.posterior.FitWarning"))
