"""The errors a user meets: bad data (file, column, row) and bad options, in one line.

Both derive from :class:`LoadbayesError` (a ``ValueError``): ``except LoadbayesError``
catches every mistake of input that the fit entry points (``fit_zip``, ``fit_exp``,
``fit_im``) and the CLI report.
"""

from __future__ import annotations

__all__ = ["DataError", "LoadbayesError", "NoDataRows", "OptionError"]


class LoadbayesError(ValueError):
    """A mistake in what the user gave (data or options); ``str(err)`` is one line."""


class OptionError(LoadbayesError):
    """A bad option value (a non-positive base, burn-in not below the draws ...)."""


class DataError(LoadbayesError):
    """Bad input data, located by file, column and row.

    ``str(err)`` is one line, e.g. ``bus18.csv: column 'v', row 17: non-numeric value
    'abc'``; parts that are None are left out. The CLI prints it and exits with code 2.

    Parameters
    ----------
    message : str
        What is wrong, without the location.
    path : str or None
        The file as the user named it (``"<stdin>"`` for standard input).
    column : str or None
        The column name.
    row : int or None
        1-based data row: the first row after the header is row 1.
    """

    def __init__(
        self,
        message: str,
        path: str | None = None,
        column: str | None = None,
        row: int | None = None,
    ) -> None:
        self.message = message
        self.path = path
        self.column = column
        self.row = row
        super().__init__(self._format())

    def _format(self) -> str:
        where = []
        if self.column is not None:
            where.append(f"column {self.column!r}")
        if self.row is not None:
            where.append(f"row {self.row}")
        parts = [self.path] if self.path is not None else []
        if where:
            parts.append(", ".join(where))
        parts.append(self.message)
        # One line whatever a file name or message holds: the CLI prints it as is.
        return ": ".join(parts).replace("\r", "\\r").replace("\n", "\\n")

    def __str__(self) -> str:
        return self._format()

    def __reduce__(self):
        # Keep the location across pickling (Dask workers send errors back).
        return (type(self), (self.message, self.path, self.column, self.row))


class NoDataRows(DataError):
    """A file with a header (or nothing) and no data rows after it.

    A :class:`DataError` like any other where one file is the input; a fleet's folder
    skips such a file with a warning instead (it holds no bus to lose).
    """
