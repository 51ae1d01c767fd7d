"""fit.track.track_zip: the ZIP coefficients after every sample, from a file in chunks."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from loadbayes.fit.track import track_zip
from loadbayes.io.errors import DataError


def _bus(path, n=600, seed=0):
    rng = np.random.default_rng(seed)
    v = 1 + 0.05 * np.sin(np.linspace(0, 12, n)) + rng.normal(0, 0.002, n)
    shape = 0.4 * v**2 + 0.3 * v + 0.3
    df = pd.DataFrame(
        {
            "t": np.arange(n) * 0.1,
            "v": v,
            "p": 2.0 * shape * (1 + rng.normal(0, 0.002, n)),
            "q": 0.5 * shape * (1 + rng.normal(0, 0.002, n)),
        }
    )
    df.to_csv(path, index=False)


def _run(path, **kw):
    track = track_zip(str(path), forgetting=0.999, **kw)
    tables = [t for t, _ in track]
    return track, pd.concat(tables, ignore_index=True)


def test_tables_do_not_depend_on_the_chunking(tmp_path):
    _bus(tmp_path / "b.csv")
    a, ta = _run(tmp_path / "b.csv", chunk_rows=1000)
    b, tb = _run(tmp_path / "b.csv", chunk_rows=37)
    pd.testing.assert_frame_equal(ta, tb)
    assert a.p0 == b.p0 and a.q0 == b.q0 and a.n_rows == b.n_rows == 600
    assert a.has_t and a.with_q and a.head_rows == 600
    assert abs(a.p0 - 2.0) < 0.05  # 'auto': estimated from the first rows
    assert list(ta.columns[:4]) == ["t", "a1_mean", "a1_low", "a1_high"]
    last = ta.iloc[-1]
    assert abs(last["a1_mean"] + last["a2_mean"] + last["a3_mean"] - 1.0) < 1e-9


def test_p_only_and_a_known_nominal_power(tmp_path):
    _bus(tmp_path / "b.csv")
    track, table = _run(tmp_path / "b.csv", q_col=None, p0=2.0, t_col=None)
    assert track.p0 == 2.0 and not track.with_q and not track.has_t
    assert "a4_mean" not in table and table["t"].iloc[0] == 1  # the data row number


def test_no_valid_rows_is_a_data_error(tmp_path):
    (tmp_path / "e.csv").write_text("v,p,q\n-1,1,1\nnan,1,1\n", encoding="utf-8")
    with pytest.raises(DataError, match="no valid rows"):
        _run(tmp_path / "e.csv", drop_invalid=True)


def test_power_zero_in_the_rows_p0_comes_from_is_refused(tmp_path):
    # P0 'auto' is estimated from the first rows and divides every later sample: 0 there
    # ended in "z and r must be finite", naming nothing.
    _bus(tmp_path / "b.csv")
    df = pd.read_csv(tmp_path / "b.csv")
    df.assign(p=0.0).to_csv(tmp_path / "dead.csv", index=False)
    with pytest.raises(DataError, match=r"dead.csv: column 'p': P is 0 in all 600 rows"):
        _run(tmp_path / "dead.csv")
    # Q 0 throughout: refused, and tracked with P alone when asked.
    df.assign(q=0.0).to_csv(tmp_path / "noq.csv", index=False)
    with pytest.raises(DataError, match=r"column 'q': Q is 0"):
        _run(tmp_path / "noq.csv")
    _run(tmp_path / "noq.csv", q_col=None)
