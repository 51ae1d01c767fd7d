"""The fleet's statistics pass: exact sums, any partitioning, bad input named."""

import math

import numpy as np
import pandas as pd
import pytest

from loadbayes.core.settings import SamplerSettings
from loadbayes.fleet import exact
from loadbayes.fleet.diagnostics import summarize
from loadbayes.fleet.partitions import ReadSpec, find_partitions
from loadbayes.fleet.run import run_fleet
from loadbayes.fleet.stats import finish, merge, partition_stats
from loadbayes.io.errors import DataError
from loadbayes.models.zip import ZIPModel


def test_exact_sum_is_the_correctly_rounded_sum_of_the_products():
    rng = np.random.default_rng(0)
    # magnitudes from 1e-300 to 1e150, both signs, cancellation: fsum is the oracle
    a = rng.standard_normal((500, 3)) * 10.0 ** rng.integers(-150, 75, (500, 3))
    a[:250, 0] = -a[250:, 0]
    acc = np.zeros((1, 6, exact.DIGITS), np.int64)
    count = np.zeros(1, np.int64)
    mins = np.full((1, 3), np.inf)
    maxs = np.full((1, 3), -np.inf)
    bad = np.zeros(1, bool)
    exact.accumulate_rows(a, np.zeros(500, np.int64), acc, count, mins, maxs, bad)
    exact.normalize(acc)
    got = exact.to_float(acc)[0]
    want = [math.fsum((a[:, i] * a[:, j]).tolist()) for i in range(3) for j in range(i, 3)]
    assert got.tolist() == want
    assert count[0] == 500 and not bad[0]


def _fleet_frame(rng, n=2000):
    return pd.DataFrame(
        {
            "bus_id": rng.choice(["a", "b", "c", "d"], n),
            "customer_class": "x",
            "v": rng.uniform(0.9, 1.1, n),
            "p": rng.normal(1, 0.1, n),
            "q": rng.normal(1, 0.1, n),
        }
    )


def test_statistics_are_bit_identical_for_any_partitioning(tmp_path):
    rng = np.random.default_rng(1)
    df = _fleet_frame(rng)
    df.to_csv(tmp_path / "all.csv", index=False)
    (tmp_path / "split").mkdir()
    for i, part in enumerate(np.array_split(np.arange(len(df)), 7)):
        df.iloc[part].to_parquet(tmp_path / "split" / f"p{i}.parquet")
    (tmp_path / "hive").mkdir()
    for bus, sub in df.groupby("bus_id"):
        d = tmp_path / "hive" / f"bus_id={bus}"
        d.mkdir()
        sub.drop(columns="bus_id").iloc[::-1].to_csv(d / "part-0.csv", index=False)
    model = ZIPModel()
    results = []
    cases = ((tmp_path / "all.csv", 300), (tmp_path / "split", 64), (tmp_path / "hive", 1000))
    for data, chunk in cases:
        spec = ReadSpec(class_col="customer_class", chunk_rows=chunk)
        parts = [partition_stats(p, spec, model) for p in find_partitions(str(data))]
        results.append(finish(merge(parts)))
        if len(parts) > 1:
            results.append(finish(merge([merge(parts[::2]), merge(parts[1::2][::-1])])))
    for r in results[1:]:
        assert r.buses.tolist() == results[0].buses.tolist()
        assert np.array_equal(r.gram, results[0].gram)
        assert np.array_equal(r.n, results[0].n)


def test_a_malformed_partition_is_named_by_file_column_and_row(tmp_path):
    rng = np.random.default_rng(2)
    _fleet_frame(rng, 50).to_csv(tmp_path / "a.csv", index=False)
    bad = _fleet_frame(rng, 50)
    bad["v"] = bad["v"].astype(object)
    bad.loc[17, "v"] = "oops"
    bad.to_csv(tmp_path / "b.csv", index=False)
    with pytest.raises(DataError) as err:
        run_fleet(str(tmp_path), ReadSpec(), sampler=SamplerSettings(draws=50, burn=10))
    msg = str(err.value)
    assert "b.csv" in msg and "column 'v'" in msg and "row 18" in msg


def test_a_bus_in_two_classes_is_refused_by_name(tmp_path):
    rng = np.random.default_rng(3)
    a, b = _fleet_frame(rng, 40), _fleet_frame(rng, 40)
    b["customer_class"] = "y"
    a.to_csv(tmp_path / "a.csv", index=False)
    b.to_csv(tmp_path / "b.csv", index=False)
    with pytest.raises(DataError, match="class"):
        run_fleet(str(tmp_path), ReadSpec(class_col="customer_class"))


@pytest.mark.parametrize("pool", ["none", "class"])
def test_thin_and_flat_buses_get_warning_rows_not_a_crash(tmp_path, pool):
    rng = np.random.default_rng(4)
    good = _fleet_frame(rng, 400)
    thin = pd.DataFrame(
        {"bus_id": "thin", "customer_class": "x", "v": [1.0, 1.02], "p": [1.0, 1.01], "q": 1.0}
    )
    flat = pd.DataFrame(
        {"bus_id": "flat", "customer_class": "x", "v": 1.01, "p": rng.normal(1, 0.01, 50), "q": 1}
    )
    pd.concat([good, thin, flat]).to_parquet(tmp_path / "f.parquet")
    res = run_fleet(
        str(tmp_path / "f.parquet"),
        ReadSpec(class_col="customer_class"),
        pool=pool,
        sampler=SamplerSettings(draws=200, burn=50),
    )
    t = res.table
    rows = t[t.bus == "thin"]
    assert len(rows) == 1 and rows.parameter.isna().all() and "fewer" in rows.warnings.iloc[0]
    flat_rows = t[t.bus == "flat"]
    assert "spread" in flat_rows.warnings.iloc[0]
    if pool == "none":  # alone, a flat bus cannot be fitted
        assert flat_rows.parameter.isna().all()
    else:  # pooled, its class identifies it
        assert flat_rows.parameter.notna().all() and (flat_rows.shrinkage.dropna() == 1).all()
    fitted = t[(t.level == "bus") & t.bus.isin(["a", "b", "c", "d"])]
    assert fitted["mean"].notna().all() and set(fitted.bus) == {"a", "b", "c", "d"}


def test_diagnostics_agree_with_arviz():
    az = pytest.importorskip("arviz")
    rng = np.random.default_rng(5)
    x = rng.standard_normal((3, 4, 400))
    x[1] = np.cumsum(x[1], axis=1) * 0.1 + x[1]  # autocorrelated
    x[2] += np.arange(4)[:, None] * 0.3  # chains disagree
    s = summarize(x, hdi_prob=0.9)
    for i in range(3):
        assert s["r_hat"][i] == pytest.approx(float(az.rhat(x[i])), rel=1e-12)
        assert s["ess_bulk"][i] == pytest.approx(float(az.ess(x[i])), rel=1e-10)
        lo, hi = az.hdi(x[i].ravel(), hdi_prob=0.9)
        assert (s["hdi_low"][i], s["hdi_high"][i]) == (lo, hi)
        assert s["sd"][i] == pytest.approx(np.std(x[i], ddof=1), rel=1e-12)


def test_bus_names_in_a_spreadsheets_code_page(tmp_path):
    # Chinese bus names saved in GB18030 (the header itself is ASCII): read as written.
    rng = np.random.default_rng(5)
    df = _fleet_frame(rng, 200)
    df["bus_id"] = "母线" + df["bus_id"]
    (tmp_path / "gb.csv").write_bytes(df.to_csv(index=False).encode("gb18030"))
    (part,) = find_partitions(str(tmp_path / "gb.csv"))
    stats = finish(partition_stats(part, ReadSpec(chunk_rows=64), ZIPModel()))
    assert sorted(stats.buses.tolist()) == ["母线a", "母线b", "母线c", "母线d"]
    # Latin-1 names are not guessed: refused at the first such row, by column and row.
    df = _fleet_frame(rng, 20)
    df.loc[6:, "bus_id"] = "Büs"
    (tmp_path / "l1.csv").write_bytes(df.to_csv(index=False).encode("latin-1"))
    (part,) = find_partitions(str(tmp_path / "l1.csv"))
    with pytest.raises(DataError) as err:
        partition_stats(part, ReadSpec(), ZIPModel())
    assert (err.value.column, err.value.row) == ("bus_id", 7)
    assert "not UTF-8 text" in str(err.value)


def test_a_bus_whose_power_is_zero_is_not_fitted_and_said_so(tmp_path):
    # An open breaker: P and Q 0 in every row. Its shares would be 0 / 0.
    rng = np.random.default_rng(6)
    good = _fleet_frame(rng, 400)
    dead = pd.DataFrame(
        {"bus_id": "dead", "customer_class": "x", "v": rng.uniform(0.95, 1.05, 60),
         "p": 0.0, "q": 0.0}
    )  # fmt: skip
    pd.concat([good, dead]).to_parquet(tmp_path / "f.parquet")
    res = run_fleet(
        str(tmp_path / "f.parquet"),
        ReadSpec(),
        p0="auto",
        q0="auto",
        sampler=SamplerSettings(draws=200, burn=50),
    )
    rows = res.table[res.table.bus == "dead"]
    assert rows.parameter.isna().all() and "P is 0 in every row" in rows.warnings.iloc[0]


def test_spaces_around_a_bus_id_do_not_make_another_bus(tmp_path):
    rng = np.random.default_rng(7)
    df = _fleet_frame(rng, 200)
    df.loc[df.index[:30], "bus_id"] = " " + df["bus_id"].iloc[:30] + "  "
    df.to_csv(tmp_path / "f.csv", index=False)
    df.to_parquet(tmp_path / "f.parquet")
    for name in ("f.csv", "f.parquet"):
        (part,) = find_partitions(str(tmp_path / name))
        stats = finish(partition_stats(part, ReadSpec(), ZIPModel()))
        assert sorted(stats.buses.tolist()) == ["a", "b", "c", "d"]
        assert int(stats.n.sum()) == 200
    # An id of spaces only is a missing id, named by its row.
    df.loc[df.index[4], "bus_id"] = "   "
    df.to_csv(tmp_path / "g.csv", index=False)
    (part,) = find_partitions(str(tmp_path / "g.csv"))
    with pytest.raises(DataError) as err:
        partition_stats(part, ReadSpec(), ZIPModel())
    assert (err.value.column, err.value.row) == ("bus_id", 5)


def test_a_copy_of_a_file_in_the_fleet_folder_is_refused(tmp_path):
    # 'part (1).parquet' left beside 'part.parquet': every bus in it counted twice.
    rng = np.random.default_rng(8)
    d = tmp_path / "d"
    d.mkdir()
    _fleet_frame(rng, 200).to_parquet(d / "part.parquet")
    _fleet_frame(rng, 200).to_csv(d / "other.csv", index=False)
    (d / "part (1).parquet").write_bytes((d / "part.parquet").read_bytes())
    with pytest.raises(DataError, match=r"the same rows as .*part.*remove one"):
        run_fleet(str(d), ReadSpec(), sampler=SamplerSettings(draws=50, burn=10))
    # The same rows in another order or format are the same rows, too.
    pd.read_parquet(d / "part.parquet").iloc[::-1].to_csv(d / "part (1).csv", index=False)
    (d / "part (1).parquet").unlink()
    with pytest.raises(DataError, match="the same rows as"):
        run_fleet(str(d), ReadSpec(), sampler=SamplerSettings(draws=50, burn=10))
