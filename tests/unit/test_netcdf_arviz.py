"""The NetCDF of a fit works with every ArviZ function: loo, plot_ppc, summary (issue 15)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from loadbayes.core.settings import DataSpec, SamplerSettings
from loadbayes.fit import fit_exp, fit_zip
from loadbayes.posterior import FitWarning, Posterior, _arviz

FAST = {"draws": 700, "burn": 200, "chains": 2, "seed": 4}
#: 2 chains x 2,500 kept draws x 300 samples = 1.5e6 values > MAX_CELLS: thinned.
LONG = {"draws": 2700, "burn": 200, "chains": 2, "seed": 4}


def _data(n=300, seed=0):
    rng = np.random.default_rng(seed)
    v = rng.uniform(0.9, 1.1, n)
    return {
        "v": 11 * v,
        "p": 5 * (0.3 * v**2 + 0.2 * v + 0.5) + rng.normal(0, 0.02, n),
        "q": 2 * (0.5 * v**2 + 0.1 * v + 0.4) + rng.normal(0, 0.02, n),
    }


@pytest.fixture(scope="module")
def zip_file(tmp_path_factory):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FitWarning)
        post = fit_zip(
            _data(),
            sampler=SamplerSettings(**LONG),
            spec=DataSpec(v_base=11, s_base=5, q0=0.4, p0=1.0),
            units={"v": "kV", "p": "MW"},
        )
    return post, post.to_netcdf(tmp_path_factory.mktemp("nc") / "fit.nc")


def test_every_group_is_there_with_units(zip_file):
    az = _arviz()
    _, path = zip_file
    idata = az.from_netcdf(str(path))
    for group in ("posterior", "sample_stats", "observed_data", "posterior_predictive",
                  "log_likelihood", "constant_data"):  # fmt: skip
        assert group in idata.groups(), group
    assert idata.observed_data["p"].attrs["units"] == "p.u. (base 5 MW)"
    assert idata.constant_data["v"].attrs["units"] == "p.u. (base 11 kV)"
    assert float(idata.posterior.attrs["v_base"]) == 11.0
    # The pointwise groups share the posterior's draw labels (thinned evenly).
    kept = idata.log_likelihood.draw.to_numpy()
    np.testing.assert_array_equal(kept, idata.posterior.draw.to_numpy())
    assert 100 < kept.size <= 1000 and "draws_thinned" in idata.posterior.attrs
    assert idata.log_likelihood["p"].shape == (2, kept.size, 300)


def test_arviz_loo_summary_and_plot_ppc_work_on_the_file(zip_file):
    az = _arviz()
    _, path = zip_file
    idata = az.from_netcdf(str(path))
    loo = az.loo(idata, var_name="p")
    # PSIS is reliable at every sample: the posterior group counts the same (thinned)
    # draws as the log-likelihood (with all draws beside a thinned log-likelihood, ArviZ's
    # relative efficiency was off by the thinning factor and every k-hat came out > 1).
    assert (loo.pareto_k.to_numpy() < 0.7).all()
    # 300 samples of Gaussian noise of sd 0.004 p.u.: elpd per sample ~ log density ~ 5.
    assert 3.0 < loo.elpd_loo / 300 < 7.0
    assert float(loo.p_loo) == pytest.approx(3.0, abs=1.5)  # a1, a2, tau_p
    s = az.summary(idata)
    assert {"a1", "a2", "a3", "tau_p"} <= set(s.index)
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    with warnings.catch_warnings():
        # ArviZ 0.x calls a matplotlib 3.11 API deprecated in that release: theirs, not ours.
        warnings.simplefilter("ignore", DeprecationWarning)
        axes = az.plot_ppc(idata, num_pp_samples=50, random_seed=0)
    assert np.size(axes) == 2  # P and Q
    plt.close("all")


def test_replicated_data_look_like_the_data(zip_file):
    post, _ = zip_file
    idata = post.to_arviz()
    y = idata.observed_data["p"].to_numpy()
    rep = idata.posterior_predictive["p"].to_numpy()
    # The replicated samples have the data's mean and spread (noise sd 0.004 p.u.).
    assert abs(rep.mean() - y.mean()) < 0.002
    assert rep.std() == pytest.approx(y.std(), rel=0.1)


def test_round_trip_keeps_inputs_and_settings(zip_file):
    post, path = zip_file
    back = Posterior.from_netcdf(path)
    np.testing.assert_array_equal(back.observed["v"], post.observed["v"])
    assert back.settings["units"] == {"v": "kV", "p": "MW"}
    # The file holds the thinned draws, said in the settings.
    kept = _arviz().from_netcdf(str(path)).posterior.draw.to_numpy()
    np.testing.assert_array_equal(back["a1"], post["a1"][:, kept])
    assert "of the 2500 kept draws" in back.settings["draws_thinned"]


def test_multiplicative_exp_likelihood_is_on_the_scale_of_p():
    rng = np.random.default_rng(1)
    v = rng.uniform(0.85, 1.05, 200)
    p = v**1.5 * np.exp(rng.normal(0, 0.01, v.size))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FitWarning)
        mult = fit_exp(
            {"v": v, "p": p},
            noise="multiplicative",
            sampler=SamplerSettings(**FAST),
            spec=DataSpec(f_col="f", p0=1.0, q0=1.0),
        )
        add = fit_exp(
            {"v": v, "p": p},
            sampler=SamplerSettings(**FAST),
            spec=DataSpec(f_col="f", p0=1.0, q0=1.0),
        )
    az = _arviz()
    a = az.loo(mult.to_arviz(), var_name="p").elpd_loo
    b = az.loo(add.to_arviz(), var_name="p").elpd_loo
    # Both are densities of P (the log form carries its 1/P Jacobian): within a few units.
    assert abs(a - b) < 10


def _same(a: Posterior, b: Posterior) -> None:
    for name in ("model", "method", "coefficients", "free", "settings", "warnings",
                 "extra_json", "written_fit_id"):  # fmt: skip
        assert getattr(a, name) == getattr(b, name), name
    for name in ("draws", "observed", "constant"):
        x, y = getattr(a, name) or {}, getattr(b, name) or {}
        assert list(x) == list(y), name
        for k in x:
            assert np.asarray(x[k]).dtype == np.asarray(y[k]).dtype, (name, k)
            np.testing.assert_array_equal(x[k], y[k], err_msg=f"{name}[{k}]")


def test_the_file_read_without_arviz_is_the_file_read_by_arviz(zip_file, cmld_lite_nc,
                                                                 tmp_path):  # fmt: skip
    # Posterior.from_netcdf reads the groups with xarray alone (no ArviZ import); the
    # same files through az.from_netcdf and from_arviz give the same Posterior: a ZIP fit
    # with its pointwise groups and thinned draws, a composite of parts' frozen draws.
    az = _arviz()
    for path in (zip_file[1], cmld_lite_nc):
        idata = az.from_netcdf(str(path))
        _same(Posterior.from_netcdf(path), Posterior.from_arviz(idata))
        idata.close()
    # A NetCDF without a posterior group is refused by both readers, in words.
    import xarray as xr

    other = tmp_path / "other.nc"
    xr.Dataset({"x": ("n", np.arange(3.0))}).to_netcdf(other, engine="h5netcdf")
    with pytest.raises(ValueError, match="no posterior group"):
        Posterior.from_netcdf(other)
    with pytest.raises(ValueError, match="no posterior group"):
        Posterior.from_arviz(az.from_netcdf(str(other)))


def test_the_groups_built_without_arviz_are_arviz_from_dicts(zip_file, cmld_lite_nc):
    # Posterior._groups (io/idata.py) against az.from_dict of the same draws, group by
    # group: variables, dims, coordinates and attributes identical (created_at aside, the
    # moment each was made); to_arviz is ArviZ's InferenceData of them.
    import xarray as xr

    from loadbayes.predictive import channel_units

    az = _arviz()
    for post in (zip_file[0], Posterior.from_netcdf(cmld_lite_nc)):
        attrs, groups = post._groups()
        units = channel_units(post)
        ref = az.from_dict(**_from_dict_args(post))
        assert list(groups) == list(ref.groups())
        assert attrs == ref.attrs
        for g, ds in groups.items():
            want = getattr(ref, g)
            want.attrs.update(attrs)  # what to_arviz then did to each group, as before
            for name in want.data_vars:
                if g in ("observed_data", "constant_data", "posterior_predictive"):
                    if name in units:
                        want[name].attrs["units"] = units[name]
            if g == "sample_stats":
                want["lp"].attrs["description"] = ds["lp"].attrs["description"]
            assert ds.attrs.pop("created_at") and want.attrs.pop("created_at")
            xr.testing.assert_identical(ds, want)
        assert list(post.to_arviz().groups()) == list(groups)


def _from_dict_args(post: Posterior) -> dict:
    # What to_arviz gave az.from_dict before io/idata.py, rebuilt from its groups' data.
    from loadbayes.predictive import pointwise

    attrs, groups = post._groups()
    pw = pointwise(post) if "log_likelihood" in groups else None
    draws = {k: groups["posterior"][k].to_numpy() for k in groups["posterior"].data_vars}
    dims, coords = {}, {}
    if "sample" in groups.get("observed_data", {"dims": {}}).dims:
        dims = {k: ["sample"] for k in [*post.observed, *(pw.log_likelihood if pw else {})]}
        coords["sample"] = groups["observed_data"]["sample"].to_numpy()
    if pw is not None and pw.draw_index.size < post.n_draws:
        coords["draw"] = pw.draw_index
    extra = {}
    if pw is not None:
        extra = {g: {k: groups[g][k].to_numpy() for k in groups[g].data_vars}
                 for g in ("posterior_predictive", "log_likelihood", "sample_stats")}  # fmt: skip
    data = {g: {k: groups[g][k].to_numpy() for k in groups[g].data_vars}
            for g in ("observed_data", "constant_data") if g in groups}  # fmt: skip
    return {"posterior": draws, "observed_data": data.get("observed_data"),
            "constant_data": data.get("constant_data"), "dims": dims or None,
            "coords": coords or None, "attrs": attrs, **extra}  # fmt: skip
