"""The one result type of every estimator: draws shaped (chain, draw), with diagnostics.

Gibbs samplers fill it with their chains; least squares and the Kalman filter fill it with
draws from their Gaussian estimate (:meth:`Posterior.from_gaussian`), so that every
comparison is one loop over the same summary, plots and exports.

Its length is one idea: the one class :class:`Posterior`, with its summaries, its ArviZ
view and its JSON and NetCDF round trips (as ArviZ keeps ``InferenceData`` in one module).

Its figure (:meth:`Posterior.plot`) is drawn by ``loadbayes.plots``, found by name as
pandas' ``DataFrame.plot`` finds its backend: the result type sits below its figures
(docs/architecture.md) and does not import them.
"""

from __future__ import annotations

import importlib
import json
import math
from collections.abc import Iterable, Mapping, Sequence
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from threadpoolctl import ThreadpoolController

from loadbayes._version import __version__
from loadbayes.core.display import summary_html

__all__ = [
    "FitWarning", "Posterior", "IDENTIFIABILITY_CORR", "fit_id", "gaussian_draws", "import_arviz",
]  # fmt: skip

#: The InferenceData groups a :class:`Posterior` is rebuilt from (``to_arviz`` writes more).
_READ_GROUPS = ("posterior", "observed_data", "constant_data")

#: The columns of :meth:`Posterior.summary` (those of ``arviz.summary``).
_SUMMARY_COLUMNS = (
    "mean", "sd", "hdi_low", "hdi_high", "mcse_mean", "mcse_sd", "ess_bulk", "ess_tail", "r_hat",
)  # fmt: skip

#: Observed inputs kept in the ``constant_data`` group (the measured P, Q are observed data).
_INPUTS = ("v", "f", "t", "ud", "uq", "ed", "eq", "w", "id", "iq", "ded", "deq", "dw", "t_s")


@cache
def _blas() -> ThreadpoolController:
    """The process's BLAS libraries, looked up once.

    ``threadpool_limits`` looks them up at every call (it reads /proc/self/maps): 3.8 ms of
    CPU a call, against 0.18 ms through one controller, measured on 30 Nov 2026; a fit
    builds a Posterior, whose identifiability check is such a call, so a coverage test's
    2000 small fits spent a fifth of their CPU there. numpy's BLAS, the one ``corrcoef``
    uses, is loaded with numpy, before the first call.
    """
    return ThreadpoolController()


class FitWarning(UserWarning):
    """A warning about the data or a fit (narrow voltage band, coefficients not separable...).

    The Python API (:func:`loadbayes.fit_zip`, :func:`loadbayes.fit_exp`,
    :func:`loadbayes.fit_im`) issues each of :attr:`Posterior.warnings` as one of these;
    silence them with ``warnings.simplefilter("ignore", FitWarning)``.
    """


#: |posterior correlation| above which two coefficients are reported as not separable.
IDENTIFIABILITY_CORR = 0.99


def gaussian_draws(
    mean: np.ndarray, cov: np.ndarray, chains: int, draws: int, rng: np.random.Generator
) -> np.ndarray:
    """Draws shaped (chains, draws, k) from N(mean, cov); cov may be singular.

    The square root is taken by eigen-decomposition (negative rounding-level eigenvalues
    clipped to zero), so a rank-deficient covariance from unidentifiable data still works.
    """
    mean = np.asarray(mean, dtype=float)
    cov = np.atleast_2d(np.asarray(cov, dtype=float))
    w, v = np.linalg.eigh((cov + cov.T) / 2)
    root = v * np.sqrt(np.clip(w, 0.0, None))
    return mean + rng.standard_normal((chains, draws, mean.size)) @ root.T


def import_arviz():
    """The ``arviz`` module, imported without its "ArviZ is undergoing" FutureWarning."""
    import warnings

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"\s*ArviZ is undergoing", category=FutureWarning)
        import arviz

    return arviz


#: The name the tests import.
_arviz = import_arviz


def _finite_or_none(x: Any) -> Any:
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, (np.integer,)):
        return int(x)
    return x


class Posterior:
    """Posterior draws of a load model's parameters, with their provenance.

    Parameters
    ----------
    draws : mapping of str to ndarray
        Each array shaped (chain, draw). Order of the mapping is the report order.
    model : str
        Model name (``"zip"``, ``"im"``, ``"exp"``, ...).
    method : str
        Estimator (``"gibbs-blocked"``, ``"least-squares"``, ``"kalman"``, ...).
    coefficients : sequence of str, optional
        The model's coefficients (reported in the correlation matrix); defaults to every
        parameter whose name does not start with ``tau``.
    free : sequence of str, optional
        The coefficients checked pairwise for identifiability; defaults to
        ``coefficients``. Leave out derived ones (a3 = 1 - a1 - a2 is perfectly
        correlated with a1 + a2 by construction, which says nothing about the data).
    observed : mapping of str to ndarray, optional
        The observed data (kept in the ``observed_data`` group).
    constant : mapping of str to ndarray, optional
        Sufficient statistics and other constants (the ``constant_data`` group).
    settings : mapping, optional
        Everything needed to reproduce the result (seed, priors, data options, n, ...).
    warnings : iterable of str, optional
        Plain-words warnings about the data or the fit; identifiability warnings are
        added automatically.
    """

    def __init__(
        self,
        draws: Mapping[str, np.ndarray],
        *,
        model: str,
        method: str,
        coefficients: Sequence[str] | None = None,
        free: Sequence[str] | None = None,
        observed: Mapping[str, np.ndarray] | None = None,
        constant: Mapping[str, np.ndarray] | None = None,
        settings: Mapping[str, Any] | None = None,
        warnings: Iterable[str] = (),
    ) -> None:
        self.draws = {k: np.asarray(v, dtype=float) for k, v in draws.items()}
        shapes = {v.shape for v in self.draws.values()}
        if len(shapes) != 1 or len(next(iter(shapes))) != 2:
            raise ValueError(f"draws must all be shaped (chain, draw); got {shapes}")
        self.model = model
        self.method = method
        self.observed = dict(observed or {})
        self.constant = dict(constant or {})
        self.settings = dict(settings or {})
        self.coefficients = list(
            coefficients
            if coefficients is not None
            else [k for k in self.draws if not k.startswith("tau")]
        )
        self.free = list(free) if free is not None else list(self.coefficients)
        #: Extra top-level keys of the JSON (e.g. the samples a robust fit flags).
        self.extra_json: dict[str, Any] = {}
        #: Quantities computed draw by draw from the parameters (e.g. dP/dV at V0), shaped
        #: (chain, draw): the JSON's ``derived`` section and the table's last rows.
        self.derived: dict[str, np.ndarray] = {}
        #: What the derived quantities are, in words (their units).
        self.derived_units: dict[str, str] = {}
        self.warnings = list(warnings)
        self.warnings.extend(w for w in self._identifiability_warnings() if w not in self.warnings)
        #: The fit id the file read held (:meth:`from_arviz`); None when built in memory
        #: or read from a file written before fit ids.
        self.written_fit_id: str | None = None

    # ------------------------------------------------------------------ basics
    @property
    def fit_id(self) -> str:
        """The fit's id (:func:`fit_id` of its settings), written into its JSON and NetCDF."""
        return fit_id(self.settings)

    @property
    def names(self) -> list[str]:
        """Parameter names, in report order."""
        return list(self.draws)

    @property
    def n_chains(self) -> int:
        """Number of chains."""
        return next(iter(self.draws.values())).shape[0]

    @property
    def n_draws(self) -> int:
        """Kept draws per chain."""
        return next(iter(self.draws.values())).shape[1]

    def __getitem__(self, name: str) -> np.ndarray:
        return self.draws[name]

    def __repr__(self) -> str:
        return (
            f"Posterior(model={self.model!r}, method={self.method!r}, "
            f"chains={self.n_chains}, draws={self.n_draws}, parameters={self.names})"
        )

    def predict(
        self,
        v: Any,
        *,
        f: Any = None,
        hdi_prob: float = 0.95,
        kind: str = "mean",
        rng: np.random.Generator | int | None = 0,
    ) -> pd.DataFrame:
        """Posterior band of P(V) (and Q(V)) in the data's units (ZIP and exponential fits).

        Parameters
        ----------
        v : array_like
            Voltages in the units of the data fitted (the bases are applied here).
        f : array_like or float, optional
            Frequency (exponential fits with frequency); nominal by default.
        hdi_prob : float
            Probability of the central band.
        kind : {"mean", "observation"}
            Band of the load curve, or of a new noisy measurement (ZIP).
        rng : Generator or int, optional
            For thinning the draws (and the observation noise).

        Returns
        -------
        pandas.DataFrame
            Columns ``v``, ``p_mean``, ``p_low``, ``p_high`` (and q), in the data's units.
        """
        from loadbayes.predictive import model_of

        model = model_of(self)
        if model is None:
            raise ValueError(f"a {self.model!r} fit has no P(V) curve to predict")
        if "level" in self.extra_json and "p0" not in self.draws:
            from loadbayes.io.errors import OptionError

            raise OptionError(
                "a drifting-level fit has no single P0 to predict with: its load is "
                "P0(t) (a1 x^2 + a2 x + a3) with the level of each moment; use the shares "
                "and post.derived (dP/dV, dQ/dV at v0), or the level's path in "
                "post.extra_json['level']"
            )
        vb = float(self.settings.get("v_base") or 1.0)
        sb = float(self.settings.get("s_base") or 1.0)
        v = np.asarray(v, dtype=float)
        kw: dict[str, Any] = {"hdi_prob": hdi_prob, "rng": rng}
        if self.model == "zip":
            kw["kind"] = kind
        elif f is not None:
            kw["f"] = f
        out = model.predict(self.draws, v / vb, **kw)
        out["v"] = v
        for col in out.columns:
            if col != "v":
                out[col] = out[col] * sb
        return out

    def warn(self, stacklevel: int = 2) -> None:
        """Issue each of :attr:`warnings` as a :class:`FitWarning` (the Python API does)."""
        import warnings as _w

        for text in self.warnings:
            _w.warn(text, FitWarning, stacklevel=stacklevel + 1)

    def _repr_html_(self) -> str:
        """A notebook's view: what was fitted, the headline table and the warnings."""
        return summary_html(self)

    def mean(self) -> dict[str, float]:
        """Posterior mean of every parameter."""
        return {k: float(v.mean()) for k, v in self.draws.items()}

    def flat(self, names: Sequence[str] | None = None) -> np.ndarray:
        """Draws of ``names`` pooled over chains, shaped (chain * draw, len(names))."""
        names = list(names or self.names)
        return np.stack([self.draws[n].reshape(-1) for n in names], axis=1)

    # ------------------------------------------------------------ summaries
    def correlation(self, names: Sequence[str] | None = None) -> pd.DataFrame:
        """Posterior correlation matrix of ``names`` (default: the coefficients)."""
        names = list(names or self.coefficients)
        x = np.stack([self.draws[n].reshape(-1) for n in names])
        # One BLAS thread: a 20 x 12,000 corrcoef (the composite fit's JSON) took 0.4 CPU
        # s (0.9 wall) on OpenBLAS's two threads of a busy machine, 1.5 ms on one.
        with np.errstate(invalid="ignore", divide="ignore"), _blas().limit(limits=1):
            c = np.corrcoef(x) if len(names) > 1 else np.ones((1, 1))
        return pd.DataFrame(np.atleast_2d(c), index=names, columns=names)

    def _identifiability_warnings(self) -> list[str]:
        names = [n for n in self.free if n in self.draws]
        if len(names) < 2:
            return []
        corr = self.correlation(names).to_numpy()
        out = []
        for i in range(len(names)):
            for j in range(i + 1, len(names)):
                r = corr[i, j]
                if np.isfinite(r) and abs(r) > IDENTIFIABILITY_CORR:
                    out.append(
                        f"{names[i]} and {names[j]} cannot be told apart on these data "
                        f"(posterior correlation {r:+.4f}): their combination is well "
                        f"determined, each alone is not. A wider voltage range, more "
                        f"samples, or an informative prior on one of them would help."
                    )
        return out

    def summary(
        self, *, hdi_prob: float = 0.95, var_names: Sequence[str] | None = None
    ) -> pd.DataFrame:
        """Mean, sd, HDI, MCSE, bulk and tail ESS and R-hat of each parameter.

        The numbers of ``arviz.summary(..., round_to="none")``, computed by the compiled
        :func:`loadbayes.core.convergence.summarize` (the fleets' too): mean, sd, HDI and
        R-hat to the last bits, ESS and MCSE to 1e-12 or so.

        Parameters
        ----------
        hdi_prob : float
            Probability mass of the highest-density interval.
        var_names : sequence of str, optional
            Parameters to summarise (default: all).

        Returns
        -------
        pandas.DataFrame
            Indexed by parameter, columns ``mean, sd, hdi_low, hdi_high, mcse_mean,
            mcse_sd, ess_bulk, ess_tail, r_hat``.
        """
        if not 0 < hdi_prob < 1:
            raise ValueError(f"hdi_prob must be in (0, 1), got {hdi_prob}")
        from loadbayes.core.convergence import summarize

        names = list(var_names or self.names)
        stats = summarize(np.stack([self.draws[n] for n in names]), hdi_prob=hdi_prob)
        return pd.DataFrame({k: stats[k] for k in _SUMMARY_COLUMNS}, index=names)

    # --------------------------------------------------------------- export
    def to_arviz(self, *, pointwise: bool = True):
        """Return an :class:`arviz.InferenceData` that every ArviZ function accepts.

        Groups: ``posterior``, ``observed_data`` (the measured P, Q), ``constant_data``
        (the inputs V, f, t and the Gram matrix), and, for models with a density of P
        (ZIP, exponential), ``posterior_predictive``, ``log_likelihood`` and
        ``sample_stats`` (``lp``, the log-likelihood of each draw), so that ``az.loo``
        and ``az.plot_ppc`` work (:mod:`loadbayes.predictive`). The pointwise groups are
        (chain, draw, sample) arrays: when all draws would make them too large, every
        group holds the same evenly thinned draws (attribute ``draws_thinned``), since
        ``az.loo`` takes its relative efficiency from the posterior's ESS. Units,
        bases, columns and timestamps are attributes of the variables and of the file.

        Parameters
        ----------
        pointwise : bool
            Add the pointwise groups; ``False`` keeps every draw and no predictions.
        """
        attrs, groups = self._groups(pointwise)
        return import_arviz().InferenceData(attrs=attrs, **groups)

    def _groups(self, pointwise: bool = True) -> tuple[dict[str, str], dict[str, Any]]:
        # The file's attributes and :meth:`to_arviz`'s groups as xarray Datasets, built
        # without ArviZ (io/idata.py): to_netcdf writes them as InferenceData would.
        from loadbayes.io.idata import GROUP_ORDER, dataset
        from loadbayes.predictive import channel_units
        from loadbayes.predictive import pointwise as _pointwise

        attrs = {
            "loadbayes_version": __version__,
            "model": self.model,
            "method": self.method,
            "fit_id": self.fit_id,
            "coefficients": json.dumps(self.coefficients),
            "free": json.dumps(self.free),
            "settings": json.dumps(self.settings, default=_json_default),
            "warnings": json.dumps(self.warnings),
        }
        if self.extra_json:  # the JSON's extra sections (a composite's identifiability)
            attrs["extra_json"] = json.dumps(self.extra_json, default=_json_default)
        units = channel_units(self)
        for key in ("data", "v_base", "s_base", "time_start", "time_end", "time_column"):
            if self.settings.get(key) is not None:
                attrs[key] = str(self.settings[key])
        measured = {k: v for k, v in self.observed.items() if k in ("p", "q")}
        inputs = {k: v for k, v in self.observed.items() if k not in measured}
        n_obs = {np.asarray(v).size for v in self.observed.values()}
        dims: dict[str, list[str]] = {}
        coords: dict[str, Any] = {}
        if len(n_obs) == 1:
            dims = {k: ["sample"] for k in self.observed}
            coords["sample"] = np.arange(1, n_obs.pop() + 1)
        pw = _pointwise(self) if pointwise and measured else None
        draws = self.draws
        extra: dict[str, Any] = {}
        if pw is not None:
            if pw.draw_index.size < self.n_draws:
                # One consistent sample for every ArviZ function: az.loo takes its
                # relative efficiency from the posterior group's ESS, which must count
                # the same draws as the log-likelihood (JSON summaries use all draws).
                draws = {k: v[:, pw.draw_index] for k, v in self.draws.items()}
                coords["draw"] = pw.draw_index
                attrs["draws_thinned"] = (
                    f"{pw.draw_index.size} of the {self.n_draws} kept draws per chain, evenly "
                    "spaced, so that the pointwise groups stay small; to_netcdf(pointwise="
                    "False) keeps every draw"
                )
            total = sum(a.sum(axis=2, dtype=float) for a in pw.log_likelihood.values())
            extra = {
                "posterior_predictive": pw.predictive,
                "log_likelihood": pw.log_likelihood,
                "sample_stats": {"lp": total},
            }
            dims.update({k: ["sample"] for k in pw.log_likelihood})
        data = {"posterior": draws, **extra, "observed_data": measured,
                "constant_data": {**inputs, **self.constant}}  # fmt: skip
        groups = {
            g: dataset(
                data[g],
                sampled=g not in ("observed_data", "constant_data"),
                dims=dims,
                coords=coords,
                attrs=attrs,
            )
            for g in GROUP_ORDER
            if data.get(g)
        }
        for group in ("observed_data", "constant_data", "posterior_predictive"):
            if group in groups:
                ds = groups[group]
                for name in ds.data_vars:
                    if name in units:
                        ds[name].attrs["units"] = units[name]
        if "sample_stats" in groups:
            groups["sample_stats"]["lp"].attrs["description"] = (
                "log-likelihood of the measured P (and Q) at each kept draw"
            )
        return attrs, groups

    def pointwise_missing(self) -> str | None:
        """Why this result has no pointwise groups (log_likelihood, posterior_predictive).

        None when :meth:`to_arviz` adds them, so that ``az.loo`` and ``az.plot_ppc`` work.
        """
        from loadbayes.predictive import model_of

        if self.settings.get("level") == "drift":
            return (
                "its level P0(t) is a path sampled with the shares and not kept, so the "
                "density of each measured sample is not in the result"
            )
        if not any(k in self.observed for k in ("p", "q")):
            return "it keeps no measured P or Q samples"
        if model_of(self) is None:
            return f"its model ({self.model}) gives no density of each measured sample here"
        return None

    def loo(self, **kwargs: Any):
        """``arviz.loo`` of the fit (PSIS leave-one-out), or a one-line error saying why not.

        Of P's log-likelihood unless ``var_name="q"`` (the groups hold one per channel,
        and ``az.loo`` takes one). Keywords go to ``az.loo``.

        Raises
        ------
        ValueError
            The result has no pointwise log-likelihood (:meth:`pointwise_missing` says
            why), so neither ``az.loo`` nor ``az.plot_ppc`` can take it.
        """
        why = self.pointwise_missing()
        if why is not None:
            raise ValueError(
                f"no log_likelihood or posterior_predictive group for this {self.model} fit "
                f"({self.method}): {why}; az.loo and az.plot_ppc need them"
            )
        kwargs.setdefault("var_name", "p")
        return import_arviz().loo(self.to_arviz(), **kwargs)

    def plot(self, **kwargs: Any) -> Any:
        """The fit's figure (a matplotlib Figure), as ``--plot`` draws it.

        A composite fit that keeps its recordings: V(t), P(t), Q(t) against them with the
        model's band (``plots/composite.py``); any other fit: the marginals, P(V) and
        Q(V) with their bands, a pair plot and a trace (``plots/fit.py``). Keywords go to
        the drawing function (``hdi_prob=``).
        """
        return importlib.import_module("loadbayes.plots").plot_result(self, **kwargs)

    def to_netcdf(
        self,
        path: str | Path,
        *,
        force: bool = False,
        pointwise: bool = True,
        atomic: bool = True,
    ) -> Path:
        """Write :meth:`to_arviz` as NetCDF, atomically (no overwrite without ``force``).

        ``atomic=False`` writes straight into ``path``: for a temporary file that the
        caller already owns and renames (an :class:`~loadbayes.io.transaction.OutputSet`'s),
        which would otherwise get a temporary of its own, and a signal at the wrong
        moment could leave that one behind (``.x.nc.XXXX.tmp.nc.YYYY.tmp.nc``).
        """
        from loadbayes.io.atomic import atomic_write, write_groups

        path = Path(path)
        if not atomic:
            write_groups(*self._groups(pointwise), path)
            return path
        with atomic_write(path, force=force) as tmp:
            write_groups(*self._groups(pointwise), tmp)
        return path

    @classmethod
    def from_arviz(cls, idata) -> Posterior:
        """Rebuild a :class:`Posterior` from an InferenceData written by :meth:`to_arviz`."""
        groups = {g: getattr(idata, g) for g in _READ_GROUPS if g in idata.groups()}
        return cls._from_groups(groups, dict(getattr(idata, "attrs", {}) or {}))

    @classmethod
    def _from_groups(cls, groups: Mapping[str, Any], root_attrs: Mapping[str, Any]) -> Posterior:
        # The groups that to_arviz writes (xarray Datasets), and the file's own attributes.
        if "posterior" not in groups:
            raise ValueError("no posterior group")
        post = groups["posterior"]
        # ArviZ keeps from_dict(attrs=...) on the InferenceData; older files on the group.
        attrs = {**dict(post.attrs), **dict(root_attrs)}
        draws = {k: post[k].to_numpy() for k in post.data_vars}
        observed = (
            {k: v.to_numpy() for k, v in groups["observed_data"].data_vars.items()}
            if "observed_data" in groups
            else None
        )
        constant = (
            {k: v.to_numpy() for k, v in groups["constant_data"].data_vars.items()}
            if "constant_data" in groups
            else None
        )
        if constant:
            # Inputs (V, f, t) live in constant_data so that plot_ppc sees only P and Q.
            observed = {
                **{k: constant.pop(k) for k in _INPUTS if k in constant},
                **(observed or {}),
            }
        out = cls(
            draws,
            model=str(attrs.get("model", "unknown")),
            method=str(attrs.get("method", "unknown")),
            coefficients=json.loads(attrs.get("coefficients", "null")),
            free=json.loads(attrs.get("free", "null")),
            observed=observed,
            constant=constant,
            settings={
                **json.loads(attrs.get("settings", "{}")),
                **({"draws_thinned": attrs["draws_thinned"]} if "draws_thinned" in attrs else {}),
            },
            warnings=json.loads(attrs.get("warnings", "[]")),
        )
        out.extra_json = json.loads(attrs.get("extra_json", "{}"))
        out.written_fit_id = str(attrs["fit_id"]) if "fit_id" in attrs else None
        return out

    @classmethod
    def from_netcdf(cls, path: str | Path) -> Posterior:
        """Read a file written by :meth:`to_netcdf`.

        The groups it needs are read with xarray, as ``arviz.from_netcdf`` reads them
        (h5netcdf, each group's Dataset and the root's attributes), without importing
        ArviZ: that import alone was 2.4 of a ``loadbayes predict``'s 6.6 s. The same
        file read by ArviZ gives the same :class:`Posterior` (``tests/unit/test_netcdf_arviz.py``).
        """
        import h5netcdf
        import xarray as xr

        path = str(path)
        with h5netcdf.File(path, mode="r") as f:
            present = [g for g in _READ_GROUPS if g in f.groups]
            root_attrs = dict(f.attrs)  # what xarray gives of the root group (all text)
        groups = {}
        for g in present:
            with xr.open_dataset(path, group=g, engine="h5netcdf") as ds:
                groups[g] = ds.load()
        return cls._from_groups(groups, root_attrs)

    def to_dict(
        self, *, hdi_prob: float = 0.95, summary: pd.DataFrame | None = None
    ) -> dict[str, Any]:
        """The JSON contract of ``loadbayes fit``: parameters, correlation, warnings.

        ``summary`` may pass a :meth:`summary` already computed at ``hdi_prob`` (it is the
        costly part: ArviZ's rank-normalised diagnostics).
        """
        s = self.summary(hdi_prob=hdi_prob) if summary is None else summary
        params = {
            name: {
                key: _finite_or_none(row[key])
                for key in ("mean", "sd", "hdi_low", "hdi_high", "r_hat", "ess_bulk", "ess_tail")
            }
            for name, row in s.iterrows()
        }
        corr = self.correlation()
        out: dict[str, Any] = {
            "model": self.model,
            "method": self.method,
            "fit_id": self.fit_id,
            "n": int(self.settings.get("n", 0)),
            "scheme": self.settings.get("scheme", self.method),
            "chains": self.n_chains,
            "draws": int(self.settings.get("draws", self.n_draws)),
            "burn": int(self.settings.get("burn", 0)),
            "thin": int(self.settings.get("thin", 1)),
            "kept_draws": self.n_draws,
            "hdi_prob": hdi_prob,
            "parameters": params,
            "correlation": {
                a: {b: _finite_or_none(corr.loc[a, b]) for b in corr.columns} for a in corr.index
            },
            "warnings": list(self.warnings),
            "loadbayes_version": __version__,
            "settings": json.loads(json.dumps(self.settings, default=_json_default)),
        }
        if self.derived:
            out["derived"] = self.derived_summary(hdi_prob=hdi_prob)
        out.update(json.loads(json.dumps(self.extra_json, default=_json_default)))
        return out

    def derived_summary(self, *, hdi_prob: float = 0.95) -> dict[str, dict[str, Any]]:
        """Mean, sd, HDI (and ESS, R-hat) of each :attr:`derived` quantity, with its unit."""
        from loadbayes.core.convergence import summarize

        names = list(self.derived)
        stats = summarize(np.stack([self.derived[n] for n in names]), hdi_prob=hdi_prob)
        out: dict[str, dict[str, Any]] = {}
        for i, name in enumerate(names):
            row: dict[str, Any] = {
                key: _finite_or_none(float(stats[key][i]))
                for key in ("mean", "sd", "hdi_low", "hdi_high", "r_hat", "ess_bulk")
            }
            if name in self.derived_units:
                row["unit"] = self.derived_units[name]
            out[name] = row
        return out

    def to_json(
        self,
        path: str | Path,
        *,
        hdi_prob: float = 0.95,
        force: bool = False,
        summary: pd.DataFrame | None = None,
    ) -> Path:
        """Write :meth:`to_dict` as JSON, atomically."""
        from loadbayes.io.atomic import atomic_write

        path = Path(path)
        d = self.to_dict(hdi_prob=hdi_prob, summary=summary)
        text = json.dumps(d, indent=2, allow_nan=False)
        with atomic_write(path, force=force) as tmp:
            Path(tmp).write_text(text + "\n", encoding="utf-8")
        return path

    # --------------------------------------------------------- constructors
    @classmethod
    def from_gaussian(
        cls,
        mean: Sequence[float],
        cov: np.ndarray,
        names: Sequence[str],
        *,
        model: str,
        method: str,
        chains: int = 4,
        draws: int = 1000,
        rng: np.random.Generator | int | None = None,
        **kwargs: Any,
    ) -> Posterior:
        """Represent a Gaussian estimate (LS, KF) by independent draws from it.

        The draws make point estimators comparable with the samplers through the same
        summary, intervals and plots; their mean is the estimate up to Monte Carlo error,
        and the exact estimate is kept in ``settings["estimate"]``.
        """
        gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        mean = np.asarray(mean, dtype=float)
        cov = np.atleast_2d(np.asarray(cov, dtype=float))
        x = gaussian_draws(mean, cov, chains, draws, gen)
        settings = dict(kwargs.pop("settings", {}) or {})
        settings.setdefault("estimate", dict(zip(names, mean.tolist(), strict=True)))
        settings.setdefault("covariance", cov.tolist())
        return cls(
            {n: x[..., i] for i, n in enumerate(names)},
            model=model,
            method=method,
            settings=settings,
            **kwargs,
        )

    def with_draws(self, extra: Mapping[str, np.ndarray]) -> Posterior:
        """A copy with transformed parameters added (e.g. a3 = 1 - a1 - a2)."""
        out = Posterior(
            {**self.draws, **extra},
            model=self.model,
            method=self.method,
            coefficients=self.coefficients,
            free=self.free,
            observed=self.observed,
            constant=self.constant,
            settings=self.settings,
            warnings=self.warnings,
        )
        out.derived, out.derived_units = dict(self.derived), dict(self.derived_units)
        return out


#: Settings that differ between two runs of the same seed (wall times) or are added when a
#: file is read (``draws_thinned``): left out of :func:`fit_id`.
_NOT_IN_FIT_ID = frozenset({"timing_s", "elapsed_s", "draws_thinned"})


def fit_id(settings: Mapping[str, Any]) -> str:
    """The id of a fit: 12 hex digits of the SHA-256 of its settings, as JSON.

    The settings hold everything that makes the draws (seed, iterations, files, the
    events' names and spans, priors, the method's options), so the JSON, the NetCDF and
    the exports of one fit carry one id, and a fit with another seed or other data another.
    Wall times are left out, so two runs of the same seed (the same draws) share their id.
    """
    import hashlib

    def strip(obj: Any) -> Any:
        if isinstance(obj, dict):
            return {k: strip(v) for k, v in obj.items() if k not in _NOT_IN_FIT_ID}
        if isinstance(obj, list):
            return [strip(v) for v in obj]
        return obj

    plain = strip(json.loads(json.dumps(dict(settings), default=_json_default)))
    text = json.dumps(plain, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:12]


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")
