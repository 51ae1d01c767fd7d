"""The straddle column of an event file read for ``validate``: booleans, 0/1, words."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from loadbayes.fit.composite.validate import read_exclusions
from loadbayes.io.errors import DataError


@pytest.mark.parametrize("suffix", ["csv", "parquet"])
@pytest.mark.parametrize(
    "column", [[False, True, False], [0, 1, 0], ["false", "TRUE", "False"], ["0", "1", "no"]]
)
def test_every_spelling_of_a_flag_reads(tmp_path, suffix, column):
    df = pd.DataFrame({"t_s": [0.0, 0.01, 0.02], "straddle": column})
    path = tmp_path / f"ev.{suffix}"
    df.to_csv(path, index=False) if suffix == "csv" else df.to_parquet(path)
    assert read_exclusions(str(path), "straddle", 3).tolist() == [False, True, False]
    assert read_exclusions(str(path), "other", 3) is None
    assert read_exclusions(str(path), "", 3) is None


def test_a_bad_flag_names_the_file_column_and_row(tmp_path):
    path = tmp_path / "ev.csv"
    pd.DataFrame({"t_s": np.arange(3.0), "straddle": ["0", "1", "2"]}).to_csv(path, index=False)
    with pytest.raises(DataError, match="'2' is not true/false") as e:
        read_exclusions(str(path), "straddle", 3)
    assert (e.value.column, e.value.row) == ("straddle", 3)
