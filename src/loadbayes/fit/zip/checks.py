"""The ZIP fit's checks and small shared steps: options, data, priors, derived quantities."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

import numpy as np

from loadbayes.core.priors import BlockPrior
from loadbayes.diagnostics import voltage_noise_warning
from loadbayes.fit.drift import confounding_warnings
from loadbayes.fit.eiv import check_v_noise as check_eiv_noise
from loadbayes.io.errors import OptionError
from loadbayes.measurements.units import (
    check_frequency,
    check_power_units,
    nominal_level_warnings,
    require_power,
)
from loadbayes.measurements.wording import refuse
from loadbayes.posterior import Posterior

__all__ = [
    "Likelihood",
    "add_derived",
    "check_likelihood",
    "check_v_noise",
    "data_checks",
    "said_confounded",
    "zip_priors",
]

#: Noise models of a ZIP fit.
Likelihood = Literal["normal", "student-t"]


def check_v_noise(v_noise: Any, likelihood: str, scheme: str) -> float | str | None:
    """The errors-in-variables option checked: None, a positive sd or "auto"."""
    value = check_eiv_noise(v_noise)
    if value is not None and (likelihood != "normal" or scheme != "blocked"):
        raise OptionError(
            "v_noise (errors in variables) has its own Gibbs sampler with the Gaussian "
            "likelihood: leave likelihood at 'normal' and scheme at 'blocked'"
        )
    return value


def check_likelihood(likelihood: str, scheme: str) -> None:
    """A known likelihood, and the Student-t one with its own (the blocked) scheme."""
    if likelihood not in ("normal", "student-t"):
        raise OptionError(f"likelihood must be 'normal' or 'student-t', got {likelihood!r}")
    if likelihood == "student-t" and scheme != "blocked":
        raise OptionError(
            f"scheme {scheme!r} is a Gaussian-likelihood scheme; the Student-t sampler has "
            "its own (leave scheme at 'blocked')"
        )


def add_derived(post: Posterior, model: Any) -> Posterior:
    """Attach the model's derived quantities (dP/dV, dQ/dV at v0) to ``post``; returns it."""
    post.derived.update(model.derived(post.draws))
    post.derived_units.update({k: model.DERIVED_UNIT for k in post.derived})
    return post


def said_confounded(post, model, cols=None, t=None):
    """Add the confounded-level warning (dP/dV < 0, or residuals that drift with time)."""
    for w in confounding_warnings(post, cols or {}, t, model):
        if w not in post.warnings:
            post.warnings.append(w)
    return post


def zip_priors(
    *,
    p0: float | str = 1.0,
    q0: float | str = 1.0,
    mean: float = 0.0,
    sd: float = 10.0,
    per_coef: Mapping[str, tuple[float, float]] | None = None,
    shape: float = 1e-3,
    rate: float = 1e-9,
    conjugate: bool = False,
) -> dict[str, BlockPrior]:
    """Priors of the P and Q blocks from plain options (the CLI's ``--prior`` flags).

    ``per_coef`` maps a1, a2 (P) and a4, a5 (Q) to (mean, sd); the others take
    (``mean``, ``sd``). With ``auto`` nominal power the block is (P0, d1, d2) and takes
    a flat-ish prior; per-coefficient priors then need a known nominal power.
    """
    per_coef = dict(per_coef or {})
    unknown = set(per_coef) - {"a1", "a2", "a4", "a5"}
    if unknown:
        raise ValueError(
            f"priors can be set on a1, a2, a4, a5 (a3 and a6 follow from the sum); got "
            f"{', '.join(sorted(unknown))}"
        )
    out: dict[str, BlockPrior] = {}
    for ch, nom, names in (("p", p0, ("a1", "a2")), ("q", q0, ("a4", "a5"))):
        if nom == "auto":
            if any(n in per_coef for n in names):
                raise ValueError(f"a prior on {'/'.join(names)} needs a known {ch}0, not 'auto'")
            out[ch] = BlockPrior.weak(3, sd=1e4, shape=shape, rate=rate, conjugate=conjugate)
            continue
        ms = [per_coef.get(n, (mean, sd)) for n in names]
        out[ch] = BlockPrior.weak(
            2,
            mean=[m for m, _ in ms],
            sd=[s for _, s in ms],
            shape=shape,
            rate=rate,
            conjugate=conjugate,
        )
    return out


def data_checks(
    cols,
    *,
    path,
    names,
    accept_units,
    wording="cli",
    v_noise=None,
    eiv=True,
    whole=True,
    f0=None,
    **nominal,
) -> list[str]:
    """The unit check (refuse, or warn with ``accept_units``) and the V-noise check.

    ``wording`` names the fixes as the CLI's options or as Python's keywords; with
    ``v_noise`` (the noise on V modelled) the V-noise check has nothing to say;
    ``eiv=False``: the fit has no such option (the exponential one), not offered.
    ``whole=False``: ``cols`` are the first chunk of a longer file, so a power that is 0
    there may not be 0 throughout (the model's Gram check refuses it then). ``f0``: the
    nominal frequency an ``f`` column is read against (the exponential model's ``kpf``).
    """
    if whole:
        require_power(cols.get("p"), cols.get("q"), path=str(path), names=names, wording=wording)
    problems = check_power_units(
        cols["v"], cols.get("p"), cols.get("q"), wording=wording, **nominal
    )
    if f0 is not None and cols.get("f") is not None:
        problems += check_frequency(cols["f"], f0, wording=wording)
    if not accept_units:
        refuse(problems, path=str(path), names=names)
    out = [f"units: {pr}" for pr in problems]
    if not problems:  # a given P0 (Q0) inside the unit check's range but off (on the
        # first chunk of a long file: its rows are the load's too)
        out += nominal_level_warnings(
            cols["v"], cols.get("p"), cols.get("q"), wording=wording, **nominal
        )
    p = cols.get("p")
    if p is not None and p.size and float(np.median(p)) < 0:
        # Fitted as it is (a negative load: the shares are fractions of a negative P0),
        # but said: a sign convention the other way round reads as generation.
        out.append(
            f"P has median {float(np.median(p)):.4g} < 0: the bus exports power (generation, "
            "or a meter that counts the other way); the shares are fractions of the exported "
            "P0, a negative load. Give P as the power into the load if that is what is meant"
        )
    noise = voltage_noise_warning(cols["v"], wording=wording, eiv=eiv) if v_noise is None else None
    return out + ([noise] if noise else [])
