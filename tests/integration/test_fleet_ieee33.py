"""The realistic case: pandapower's 33-bus feeder with a ZIP load on every bus, pooled."""

import numpy as np
import pytest

from loadbayes.core.settings import SamplerSettings
from loadbayes.fleet.generate import ieee33_fleet
from loadbayes.fleet.partitions import ReadSpec
from loadbayes.fleet.run import run_fleet

pytestmark = pytest.mark.integration
pytest.importorskip("pandapower")


def test_pooled_fit_recovers_the_class_mixes_of_the_33_bus_feeder(tmp_path):
    rows, truth = ieee33_fleet(24, seed=5)
    assert rows["bus_id"].nunique() == 32 and rows["v"].max() - rows["v"].min() > 0.05
    rows.to_parquet(tmp_path / "feeder.parquet")
    res = run_fleet(
        str(tmp_path / "feeder.parquet"),
        ReadSpec(class_col="customer_class"),
        pool="class",
        sampler=SamplerSettings(draws=800, burn=200),
    )
    t = res.table
    cls = t[t.level == "class"].set_index(["class", "parameter"])
    mixes = truth.groupby("customer_class")[["a1", "a2", "a4", "a5"]].first()
    # Within 4 posterior sd of the truth (false alarm < 1e-3 for 12 near-normal checks).
    for name, true in mixes.iterrows():
        for par in ("a1", "a2", "a4", "a5"):
            row = cls.loc[(name, par)]
            assert abs(row["mean"] - true[par]) < 4 * row["sd"], (name, par, row["mean"])
    bus = t[(t.level == "bus") & t.parameter.notna()]
    assert bus["bus"].nunique() == 32 and np.isfinite(bus["mean"]).all()
