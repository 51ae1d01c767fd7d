"""Which load model do the data support? ZIP against exponential by PSIS-LOO (ArviZ).

Every candidate's pointwise log-likelihood is computed here from its posterior draws and
the data, as the log *density of the measured power in data units*, so the candidates
are compared on one scale whatever scale they were fitted on:

* ZIP and additive exponential with a known P0 are fitted on ``y = P / P0``:
  ``log p(P) = log N(y | mu, 1/tau) - log |P0|``;
* with ``p0="auto"`` they are fitted on P itself: no Jacobian;
* the multiplicative exponential is fitted on ``log(P / P0)``:
  ``log p(P) = log N(log(P / P0) | mu, 1/tau) - log P`` (the Jacobian ``1/P``); it is
  only defined where ``P > 0``;
* the Student-t ZIP (``fit_robust``) uses the t density with its ``nu``.

The log-likelihood draws go into the ``log_likelihood`` group of an
:class:`arviz.InferenceData` (built here, :mod:`loadbayes.posterior` is unchanged) and
:func:`arviz.compare` ranks the candidates by expected log predictive density (ELPD).
A difference is called decisive when it exceeds four standard errors of the difference
(``dse``) and 4 nats; below two standard errors, or below 4 nats, the data are said not
to tell the models apart (an ELPD difference under 4 is small whatever its standard
error: the LOO FAQ's rule, Sivula, Magnusson & Vehtari 2022).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from scipy import special

__all__ = [
    "ModelChoice",
    "compare",
    "compare_zip_exp",
    "html_section",
    "inference_data",
    "pointwise_loglik",
    "run",
    "verdict",
]

#: ELPD difference / dse above which the better model is called clearly supported ...
DECISIVE_SE = 4.0
#: ... and below which the data are said not to tell the models apart.
UNDECIDED_SE = 2.0
#: ELPD differences below this many nats are small whatever their standard error (the
#: LOO FAQ's rule, Sivula, Magnusson & Vehtari 2022): two nearly identical models have a
#: tiny ``dse`` and would otherwise be "decisively" separated by a fraction of a nat.
SMALL_ELPD = 4.0


def _arviz():
    import warnings

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"\s*ArviZ is undergoing", category=FutureWarning)
        import arviz

    return arviz


def _thin(post, max_draws: int) -> tuple[dict[str, np.ndarray], int]:
    step = max(int(math.ceil(post.n_draws / max_draws)), 1)
    return {k: v[:, ::step] for k, v in post.draws.items()}, step


def _normal_ll(x: np.ndarray, mu: np.ndarray, tau: np.ndarray) -> np.ndarray:
    return 0.5 * (np.log(tau) - math.log(2 * math.pi)) - 0.5 * tau * (x - mu) ** 2


def _t_ll(x: np.ndarray, mu: np.ndarray, tau: np.ndarray, nu: np.ndarray) -> np.ndarray:
    u = tau * (x - mu) ** 2
    return (
        special.gammaln((nu + 1) / 2)
        - special.gammaln(nu / 2)
        - 0.5 * np.log(nu * math.pi)
        + 0.5 * np.log(tau)
        - (nu + 1) / 2 * np.log1p(u / nu)
    )


def pointwise_loglik(
    post: Any,
    data: Mapping[str, np.ndarray],
    *,
    channel: str = "p",
    max_draws: int = 1000,
) -> np.ndarray:
    """Log density of each measured sample of one channel under each posterior draw.

    Parameters
    ----------
    post : Posterior
        A ZIP (Gaussian or Student-t) or exponential fit; its ``settings`` say how it
        was fitted (``v0``, ``p0``, ``noise``, ``f0``, ``nu``).
    data : mapping
        The data it was fitted to: ``v``, ``p`` (``q``, ``f``).
    channel : {"p", "q"}
        Power channel.
    max_draws : int
        Draws per chain kept (evenly thinned).

    Returns
    -------
    ndarray, shape (chain, draw, n)
        ``log p(P_i | theta)`` in the units of the data (see the module notes).
    """
    st = post.settings
    draws, _ = _thin(post, max_draws)
    v = np.asarray(data["v"], dtype=float)
    obs = np.asarray(data[channel], dtype=float)
    x = v / float(st.get("v0", 1.0))
    nom = st.get(f"{channel}0", 1.0)
    auto = nom == "auto"
    tau = draws[f"tau_{channel}"][..., None]

    def d(name: str) -> np.ndarray:
        return draws[name][..., None]

    if post.model == "zip":
        names = ("a1", "a2", "a3") if channel == "p" else ("a4", "a5", "a6")
        shape = d(names[0]) * x**2 + d(names[1]) * x + d(names[2])
        scale = d(f"{channel}0") if auto else float(nom)
        target = obs if auto else obs / scale
        mu = shape * scale if auto else shape
        if st.get("likelihood") == "student-t":
            nu = draws.get(f"nu_{channel}")
            nu = np.full_like(tau, float(st["nu"])) if nu is None else nu[..., None]
            ll = _t_ll(target, mu, tau, nu)
        else:
            ll = _normal_ll(target, mu, tau)
        return ll if auto else ll - math.log(abs(float(nom)))
    if post.model == "exp":
        e, kf = ("np", "kpf") if channel == "p" else ("nq", "kqf")
        lx = np.log(x)
        df = 0.0
        if kf in draws:
            df = (np.asarray(data["f"], dtype=float) - float(st["f0"])) / float(st["f0"])
        if st.get("noise") == "multiplicative":
            with np.errstate(divide="ignore", invalid="ignore"):
                ly = np.log(obs if auto else obs / float(nom))
            mu = d(e) * lx + (d(kf) * df if kf in draws else 0.0)
            if auto:
                mu = mu + np.log(d(f"{channel}0"))
            with np.errstate(divide="ignore", invalid="ignore"):
                ll = _normal_ll(ly, mu, tau) - np.log(np.abs(obs))
            return np.where(obs / (1.0 if auto else float(nom)) > 0, ll, -np.inf)
        fac = 1.0 + d(kf) * df if kf in draws else 1.0
        shape = np.exp(d(e) * lx) * fac
        if auto:
            return _normal_ll(obs, d(f"{channel}0") * shape, tau)
        return _normal_ll(obs / float(nom), shape, tau) - math.log(abs(float(nom)))
    raise ValueError(f"no pointwise likelihood for model {post.model!r}")


def inference_data(post: Any, data: Mapping[str, np.ndarray], *, channel="p", max_draws=1000):
    """An :class:`arviz.InferenceData` with ``posterior`` and ``log_likelihood`` groups."""
    az = _arviz()
    draws, _ = _thin(post, max_draws)
    ll = pointwise_loglik(post, data, channel=channel, max_draws=max_draws)
    return az.from_dict(
        posterior={k: v for k, v in draws.items() if np.all(np.isfinite(v))},
        log_likelihood={channel: ll},
        observed_data={channel: np.asarray(data[channel], dtype=float)},
    )


def compare(
    posts: Mapping[str, Any],
    data: Mapping[str, np.ndarray],
    *,
    channel: str = "p",
    ic: str = "loo",
    max_draws: int = 1000,
) -> pd.DataFrame:
    """ArviZ's model comparison table (ELPD, its SE, differences, Pareto-k warnings).

    Parameters
    ----------
    posts : mapping of str to Posterior
        Candidates by name, all fitted to ``data``.
    data : mapping
        The data.
    channel : {"p", "q"}
        Channel compared.
    ic : {"loo", "waic"}
        Criterion.
    max_draws : int
        Draws per chain used.

    Returns
    -------
    pandas.DataFrame
        :func:`arviz.compare` output plus ``max_pareto_k`` (LOO only) and ``z``
        (``elpd_diff / dse``).
    """
    import warnings

    az = _arviz()
    idata = {
        k: inference_data(p, data, channel=channel, max_draws=max_draws) for k, p in posts.items()
    }
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        warnings.simplefilter("ignore", RuntimeWarning)
        table = az.compare(idata, ic=ic)
        if ic == "loo":
            ks = {k: float(np.max(az.loo(v, pointwise=True).pareto_k)) for k, v in idata.items()}
            table["max_pareto_k"] = [ks[i] for i in table.index]
    with np.errstate(divide="ignore", invalid="ignore"):
        table["z"] = np.where(table["dse"] > 0, table["elpd_diff"] / table["dse"], 0.0)
    return table


def verdict(table: pd.DataFrame) -> str:
    """One sentence: which model the data support, from a :func:`compare` table."""
    names = list(table.index)
    best = names[0]
    if len(names) < 2:
        return f"only {best} was fitted"
    parts = []
    for other in names[1:]:
        z = float(table.loc[other, "z"])
        diff = float(table.loc[other, "elpd_diff"])
        num = f"ELPD difference {diff:.1f}, {z:.1f} standard errors"
        if z < UNDECIDED_SE:
            parts.append(f"the data cannot tell {best} and {other} apart ({num})")
        elif diff < SMALL_ELPD:
            # Many standard errors but a fraction of a few nats: precise, and too small to
            # matter (the LOO FAQ's rule) -- not "cannot tell apart", which z contradicts.
            parts.append(
                f"{best} and {other} fit about equally well ({num}: a difference under "
                f"{SMALL_ELPD:g}, too small to matter whatever its standard error)"
            )
        elif z >= DECISIVE_SE:
            parts.append(f"the data clearly support {best} over {other} ({num})")
        else:
            parts.append(f"the data lean towards {best} over {other} ({num}; not decisive)")
    return "; ".join(parts)


def compare_zip_exp(
    data: Mapping[str, np.ndarray],
    *,
    v0: float = 1.0,
    p0: float | str = 1.0,
    exp_noise: str = "additive",
    draws: int = 3000,
    burn: int = 1000,
    chains: int = 2,
    seed: int = 0,
    student_t: bool = False,
) -> pd.DataFrame:
    """Fit ZIP and exponential (P only) to the same data and compare them by LOO."""
    from loadbayes.core.settings import DataSpec
    from loadbayes.fit import fit_exp, fit_zip
    from loadbayes.fit.sampler import MODEL_DEFAULTS

    cols = {"v": np.asarray(data["v"], float), "p": np.asarray(data["p"], float)}
    if "f" in data:
        cols["f"] = np.asarray(data["f"], float)
    smp = MODEL_DEFAULTS.with_(draws=draws, burn=burn, chains=chains, seed=seed)
    spec = DataSpec(v0=v0, p0=None if p0 == "auto" else p0)  # type: ignore[arg-type]
    posts = {
        # The study records each fit's warnings itself; no Python warnings on the way.
        "zip": fit_zip(cols, spec=spec, with_q=False, warn=False, sampler=smp),
        "exponential": fit_exp(
            cols,
            spec=spec.with_(f_col="f"),
            with_q=False,
            noise=exp_noise,
            warn=False,
            sampler=smp,
        ),  # fmt: skip
    }
    if student_t:
        from loadbayes.fit import fit_robust
        from loadbayes.models.zip import ZIPModel

        model = ZIPModel(v0=v0, p0=p0, with_q=False)  # type: ignore[arg-type]
        posts["zip-student-t"] = fit_robust(model, cols, settings={"v0": v0, "p0": p0}, sampler=smp)
    return compare(posts, cols)


# ------------------------------------------------------------------------ study
@dataclass
class ModelChoice:
    """Results of :func:`run`: one comparison table per data set."""

    tables: dict[str, pd.DataFrame] = field(default_factory=dict)
    settings: dict[str, Any] = field(default_factory=dict)

    def summary(self) -> pd.DataFrame:
        """One row per data set: the preferred model, ELPD difference, SE, verdict."""
        rows = []
        for name, t in self.tables.items():
            second = t.index[1]
            rows.append(
                {
                    "data": name,
                    "preferred": t.index[0],
                    "runner_up": second,
                    "elpd_diff": float(t.loc[second, "elpd_diff"]),
                    "dse": float(t.loc[second, "dse"]),
                    "z": float(t.loc[second, "z"]),
                    "max_pareto_k": float(t["max_pareto_k"].max()),
                    "verdict": verdict(t),
                }
            )
        return pd.DataFrame(rows)


def run(*, quick: bool = True, seed: int = 0, smoke: bool = False) -> ModelChoice:
    """Compare ZIP and exponential on the paper's 33-bus data and on two controls.

    Data sets (P at bus 18, P0 known, n = 300 quick / 1000 full):

    * ``33-bus, 10% noise``: the paper's experiments (true ZIP 0.25, 0.25, 0.5);
    * ``33-bus, 1% noise``: the same power flows, ten times less noise;
    * ``exponential truth, 1% noise``: the same bus-18 voltages with
      ``P = x^0.6`` (the exponent that best matches the ZIP curve there) plus noise: a
      control where the exponential model is true;
    * ``33-bus, 10% noise, 5% spikes``: the paper's data with bad samples, comparing
      the Gaussian and the Student-t ZIP too.

    ``smoke``: n = 150 and 400 draws (100 burn-in), a check of the pipeline, not a result.
    """
    from loadbayes.cases.scenarios import corrupt, paper_data

    n = 150 if smoke else 300 if quick else 1000
    draws, burn = (400, 100) if smoke else (2000, 500) if quick else (6000, 1000)
    sampler = {"draws": draws, "burn": burn, "chains": 2}
    out = ModelChoice(settings={"n": n, "seed": seed, **sampler, "criterion": "PSIS-LOO"})
    for noise in (0.1, 0.01):
        df = paper_data(n, noise_sd=noise, seed=seed, noise_seed=1)
        data = {"v": df["v_pu"].to_numpy(), "p": df["p_meas_pu"].to_numpy()}
        out.tables[f"33-bus ZIP truth, {noise:.0%} noise"] = compare_zip_exp(
            data, seed=seed, **sampler
        )
    df = paper_data(n, noise_sd=0.0, seed=seed)
    gen = np.random.default_rng(np.random.SeedSequence([seed, 99]))
    v = df["v_pu"].to_numpy()
    data = {"v": v, "p": v**0.6 + 0.01 * gen.standard_normal(v.size)}
    out.tables["exponential truth (np = 0.6), 1% noise"] = compare_zip_exp(
        data, seed=seed, **sampler
    )
    df = corrupt(
        paper_data(n, noise_sd=0.1, seed=seed, noise_seed=1), kind="spike", fraction=0.05, seed=seed
    )
    data = {"v": df["v_pu"].to_numpy(), "p": df["p_meas_pu"].to_numpy()}
    out.tables["33-bus, 10% noise, 5% spikes"] = compare_zip_exp(
        data, seed=seed, student_t=True, **sampler
    )
    return out


def html_section(result: ModelChoice) -> str:
    """The model-choice section of the report (an HTML ``<section>``)."""
    from loadbayes.studies.report import escape, table_html

    st = result.settings
    parts = [
        '<section id="model-choice">',
        "<h2>Which model do the data support? ZIP against exponential (PSIS-LOO)</h2>",
        "<p>Each candidate's pointwise log-likelihood is the density of the measured P "
        "in per unit (Jacobian applied where a model is fitted on another scale); "
        f"ArviZ's <code>compare</code> ranks them by ELPD. n = {st.get('n')}, "
        f"{st.get('chains')} chains x {st.get('draws')} iterations "
        f"({st.get('burn')} burn-in), seed {st.get('seed')}. A difference above "
        f"{DECISIVE_SE:g} standard errors is called decisive, below {UNDECIDED_SE:g} "
        "undecided.</p>",
    ]
    summ = result.summary().set_index("data")
    parts.append(table_html(summ.drop(columns=["verdict"]), float_format="{:.3g}"))
    parts.append(
        "<ul>"
        + "".join(f"<li>{escape(k)}: {escape(v)}.</li>" for k, v in summ["verdict"].items())
        + "</ul>"
    )
    parts.append("</section>")
    return "\n".join(parts)
