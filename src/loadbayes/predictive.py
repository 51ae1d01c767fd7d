"""Pointwise predictions of a fit: the posterior-predictive draws and the log-likelihood.

A :class:`~loadbayes.posterior.Posterior` holds draws and the settings of its fit, not the
model object; this module rebuilds the model from those settings (ZIP and exponential:
the models whose likelihood is a density of the measured P and Q) and evaluates, draw by
draw, the mean power at every observed voltage, the log-density of each measurement and a
replicated measurement. ArviZ's ``log_likelihood`` and ``posterior_predictive`` groups are
made of these, so that ``az.loo`` and ``az.plot_ppc`` work on a saved fit.

The arrays are (chain, draw, sample): at 1,440 samples and 35,000 draws a chain they would
be 1.6 GB, so the draws are thinned evenly to keep each array under ``max_cells`` values
(stored as float32); the kept draws' indices are the ``draw`` coordinate, and
:meth:`Posterior.to_arviz` thins the posterior group to the same draws.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "Pointwise",
    "channel_units",
    "curves",
    "data_units",
    "model_of",
    "param_unit",
    "pointwise",
]

#: Largest number of values of one pointwise array (chain x draw x sample): 4 MB as float32.
MAX_CELLS = 1_000_000

#: Draws kept per chain at most for the pointwise groups.
MAX_DRAWS = 1000


@dataclass
class Pointwise:
    """Pointwise groups of a fit: per channel, arrays shaped (chain, kept draw, sample)."""

    draw_index: np.ndarray
    log_likelihood: dict[str, np.ndarray]
    predictive: dict[str, np.ndarray]
    mean: dict[str, np.ndarray]


def model_of(post: Any) -> Any | None:
    """The model a fit used, rebuilt from its settings; None for models with no P(V).

    Parameters
    ----------
    post : Posterior
        A ZIP or exponential fit (draws named a1.. or np..).

    Returns
    -------
    ZIPModel, ExponentialModel or None
    """
    st = post.settings
    nominal = {k: _nominal(st.get(k)) for k in ("p0", "q0")}
    v0 = float(st.get("v0") or 1.0)
    if post.model == "zip" and "a1" in post.draws:
        from loadbayes.models.zip import ZIPModel

        return ZIPModel(v0=v0, with_q="a4" in post.draws, **nominal)
    if post.model == "exp" and "np" in post.draws:
        from loadbayes.models.exponential import ExponentialModel

        return ExponentialModel(
            v0=v0,
            with_q="nq" in post.draws,
            with_f="kpf" in post.draws,
            f0=float(st.get("f0") or 60.0),
            noise=st.get("noise") or "additive",
            **nominal,
        )
    return None


def _nominal(value: Any) -> float | str:
    if value is None:
        return 1.0
    return "auto" if value == "auto" else float(value)


def channel_units(post: Any) -> dict[str, str]:
    """Units of v, p, q, f as fitted: per unit of the given bases, or the data's own."""
    st = post.settings
    units = dict(st.get("units") or {})
    vb, sb = st.get("v_base"), st.get("s_base")
    out = {
        "v": f"p.u. (base {vb:g} {units.get('v', 'data units')})" if vb else units.get("v", "p.u."),
        "p": f"p.u. (base {sb:g} {units.get('p', 'data units')})" if sb else units.get("p", "p.u."),
        "q": f"p.u. (base {sb:g} {units.get('q', 'data units')})" if sb else units.get("q", "p.u."),
        "f": units.get("f", "Hz"),
    }
    return out


def data_units(post: Any) -> dict[str, str]:
    """Units of v, p, q, f in the data as read (what the user's file holds)."""
    st = post.settings
    units = dict(st.get("units") or {})
    out = {}
    for key, base in (("v", "v_base"), ("p", "s_base"), ("q", "s_base")):
        out[key] = units.get(key) or ("data units" if st.get(base) else "p.u.")
    out["f"] = units.get("f", "Hz")
    return out


#: Units of the coefficients (docs/zip.md, docs/motor.md).
_PARAM_UNITS = {
    **{f"a{i}": "share of nominal power" for i in range(1, 7)},
    "np": "dimensionless", "nq": "dimensionless", "kpf": "dimensionless",
    "kqf": "dimensionless", "b1": "1/s", "b2": "p.u./s", "b3": "1/s", "ab": "p.u.",
    "ac": "p.u.", "rs": "p.u.", "xp": "p.u.", "x": "p.u.", "xs": "p.u.", "xm": "p.u.",
    "xr": "p.u.", "rr": "p.u.", "tp_s": "s", "h_s": "s",
}  # fmt: skip


def param_unit(name: str, post: Any) -> str:
    """The unit of a parameter of this fit, in words (for axes and tables)."""
    if name in _PARAM_UNITS:
        return _PARAM_UNITS[name]
    fitted = channel_units(post)
    if name in ("p0", "q0"):
        return fitted[name[0]]
    if name.startswith("tau_"):
        ch = name[4:]
        if post.model in ("zip", "exp") and ch in ("p", "q"):
            nom = post.settings.get(f"{ch}0")
            if post.settings.get("noise") == "multiplicative":
                return "1/(log units)²"
            return f"1/({fitted[ch]})²" if nom == "auto" else f"1/({ch.upper()}/{ch.upper()}0)²"
        return "1/(equation units)²"
    return "–"


def curves(model: Any, draws: Mapping[str, np.ndarray], obs: Mapping[str, np.ndarray]):
    """Mean P (Q) at the voltages ``obs["v"]`` per draw, and the noise sd per draw.

    ``draws`` are flat (one value a draw); returns ``({channel: (S, n)}, {channel: (S,)})``
    in the fitted units (per unit when bases were given).
    """
    return _curves(model, draws, obs)


def _curves(model: Any, draws: Mapping[str, np.ndarray], obs: Mapping[str, np.ndarray]):
    """Mean P (Q) at each observed sample, per draw: {channel: (S, n)}, and the noise sd."""
    from loadbayes.models.zip import ZIPModel

    v = np.asarray(obs["v"], dtype=float)
    x = v / model.v0
    means, sds = {}, {}
    if isinstance(model, ZIPModel):
        for ch, nom, (c1, c2, c3) in model._channels():
            a = [draws[c][:, None] for c in (c1, c2, c3)]
            scale = draws[f"{ch}0"][:, None] if nom == "auto" else float(nom)
            means[ch] = scale * (a[0] * x**2 + a[1] * x + a[2])
            sds[ch] = (1.0 if nom == "auto" else abs(float(nom))) / np.sqrt(draws[f"tau_{ch}"])
        return means, sds
    df = 0.0
    if model.with_f and "f" in obs:
        df = (np.asarray(obs["f"], dtype=float) - model.f0) / model.f0
    for ch, nom, *_ in model.channels():
        means[ch] = model.curve(draws, ch, x, df)
        tau = draws[f"tau_{ch}"]
        if model.noise == "multiplicative":
            sds[ch] = 1.0 / np.sqrt(tau)
        else:
            sds[ch] = (1.0 if nom == "auto" else abs(float(nom))) / np.sqrt(tau)
    return means, sds


def pointwise(
    post: Any,
    *,
    max_cells: int = MAX_CELLS,
    rng: np.random.Generator | int | None = None,
) -> Pointwise | None:
    """Log-likelihood and posterior-predictive draws at every observed sample.

    Parameters
    ----------
    post : Posterior
        A fit with observed ``v`` and ``p`` (``q``) kept.
    max_cells : int
        Largest chain x draw x sample size of one array; draws are thinned evenly to fit.
    rng : Generator or int, optional
        For the replicated measurements; by default the fit's seed.

    Returns
    -------
    Pointwise or None
        None when the model has no density of P (the motor) or no data were kept.
    """
    model = model_of(post)
    obs = post.observed
    if model is None or "v" not in obs or "p" not in obs:
        return None
    chans = [c for c in ("p", "q") if c in obs and f"tau_{c}" in post.draws]
    n = int(np.asarray(obs["v"]).size)
    if n == 0:
        return None
    per_chain = max(1, min(post.n_draws, MAX_DRAWS, max_cells // max(1, post.n_chains * n)))
    idx = np.unique(np.linspace(0, post.n_draws - 1, per_chain).round().astype(int))
    seed = post.settings.get("seed", 0) if rng is None else rng
    gen = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    sub = {k: v[:, idx].reshape(-1) for k, v in post.draws.items()}
    means, sds = _curves(model, sub, obs)
    shape = (post.n_chains, idx.size, n)
    ll, pp, mu = {}, {}, {}
    for ch in chans:
        y = np.asarray(obs[ch], dtype=float)[None, :]
        m, sd = means[ch], sds[ch][:, None]
        if getattr(model, "noise", "additive") == "multiplicative":
            with np.errstate(divide="ignore", invalid="ignore"):
                logy = np.log(y)
                z = (logy - np.log(m)) / sd
                # The density of P itself (Jacobian 1/P), so LOO compares with additive fits.
                ll[ch] = -0.5 * z**2 - np.log(sd) - 0.5 * np.log(2 * np.pi) - logy
            pp[ch] = m * np.exp(sd * gen.standard_normal(m.shape))
        else:
            z = (y - m) / sd
            ll[ch] = -0.5 * z**2 - np.log(sd) - 0.5 * np.log(2 * np.pi)
            pp[ch] = m + sd * gen.standard_normal(m.shape)
        ll[ch] = ll[ch].reshape(shape).astype(np.float32)
        pp[ch] = pp[ch].reshape(shape).astype(np.float32)
        mu[ch] = m.reshape(shape)
    return Pointwise(idx, ll, pp, mu)
