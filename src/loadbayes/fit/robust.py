"""Student-t fits of a linear load model: flagged samples, robust coefficients."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Literal

import numpy as np

from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.sampler import MODEL_DEFAULTS, new_spelling
from loadbayes.inference import robust
from loadbayes.inference.robust import FLAG_SIGMAS, NU_BOUNDS, NU_PRIOR, flag_threshold
from loadbayes.posterior import Posterior

__all__ = ["fit_robust"]


@new_spelling()
def fit_robust(
    model: Any,
    data: Mapping[str, np.ndarray],
    *,
    priors: Mapping[str, BlockPrior] | None = None,
    nu: float | Literal["auto"] = "auto",
    sampler: SamplerSettings | None = None,
    flag_sigmas: float = FLAG_SIGMAS,
    observed: Mapping[str, np.ndarray] | None = None,
    settings: Mapping[str, Any] | None = None,
    warnings: Sequence[str] = (),
):
    """Student-t fit of every block of a linear load model, as a :class:`Posterior`.

    Parameters
    ----------
    model : object
        A model with ``rows``, ``gram_columns``, ``blocks``, ``coefficients``,
        ``transform`` and ``default_priors`` (e.g. :class:`loadbayes.models.zip.ZIPModel`);
        nothing here depends on what the blocks mean.
    data : mapping of str to ndarray
        The model's input columns, in memory (every iteration visits every sample).
    priors : mapping, optional
        One :class:`BlockPrior` per block name; ``model.default_priors()`` otherwise.
    nu : float or "auto"
        Degrees of freedom of every block (each block has its own ``nu_<block>``).
    sampler : SamplerSettings, optional
        How the chains run (:data:`loadbayes.fit.core.MODEL_DEFAULTS` by default); each
        block gets its own child of its ``seed`` (an int, a ``SeedSequence`` or None).
    flag_sigmas : float
        Flag rule (module notes).
    observed, settings, warnings
        Passed to the :class:`Posterior`.

    Returns
    -------
    Posterior
        The model's parameters plus ``nu_<block>``; ``constant`` holds the mean weight of
        each sample per block (``weight_<block>``) and ``settings["flagged"]`` the 0-based
        indices of flagged samples per block.
    """
    smp = sampler if sampler is not None else MODEL_DEFAULTS
    chains, draws, burn, thin = smp.chains, smp.draws, smp.burn, smp.thin
    init, seed = smp.init, smp.seed
    rows = model.rows(data)
    names = tuple(model.gram_columns)
    priors = dict(priors or model.default_priors())
    seq = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    raw: dict[str, np.ndarray] = {}
    extra: dict[str, np.ndarray] = {}
    constant: dict[str, np.ndarray] = {}
    flagged: dict[str, list[int]] = {}
    accept: dict[str, float | None] = {}
    blocks = list(model.blocks)
    for block, child in zip(blocks, seq.spawn(len(blocks)), strict=True):
        z, r = block.equations_of(rows, names)
        # Looked up on the module at call time, so a test can swap the kernel for a broken one.
        res = robust.sample_student_t(
            z, r, priors[block.name], nu=nu, settings=smp.with_(seed=child)
        )
        for i, cname in enumerate(block.coef_names):
            raw[cname] = res.coef[..., i]
        raw[block.tau_name] = res.tau
        extra[f"nu_{block.name}"] = res.nu
        n_eq = len(block.equations)
        weight = res.weight.reshape(-1, n_eq).min(axis=1)  # a sample: its worst equation
        constant[f"weight_{block.name}"] = weight
        thr = flag_threshold(res.nu, sigmas=flag_sigmas)
        flagged[block.name] = np.flatnonzero(weight < thr).tolist()
        acc = float(np.nanmean(res.accept_nu)) if np.any(np.isfinite(res.accept_nu)) else None
        accept[block.name] = acc
    draws_out = model.transform(raw)
    if nu != "auto":
        extra = {}  # a fixed nu is a setting, not a parameter
    draws_out.update(extra)
    full = dict(settings or {})
    full.update(
        n=int(rows.shape[0]),
        likelihood="student-t",
        nu=nu,
        nu_prior=list(NU_PRIOR) if nu == "auto" else None,
        nu_bounds=list(NU_BOUNDS) if nu == "auto" else None,
        nu_acceptance=accept,
        flag_rule=(
            f"mean weight < (nu + 1) / (nu + {flag_sigmas:g}^2), nu = posterior median "
            f"(or the fixed value): discounted like a {flag_sigmas:g}-scale residual"
        ),
        flagged=flagged,
        scheme="student-t",
        chains=chains,
        draws=draws,
        burn=burn,
        thin=thin,
        init=init,
        seed=seed if not isinstance(seed, np.random.SeedSequence) else None,
        priors={
            k: {
                "mean": p.mean.tolist(),
                "precision": p.precision.tolist(),
                "shape": p.shape,
                "rate": p.rate,
                "conjugate": p.conjugate,
            }
            for k, p in priors.items()
        },
    )
    n_flag = sorted({i for v in flagged.values() for i in v})
    warn = list(warnings)
    if n_flag:
        warn.append(
            f"{len(n_flag)} of {rows.shape[0]} samples look like bad data (Student-t weight "
            "below the flag threshold); they are listed under 'flagged'."
        )
    return Posterior(
        draws_out,
        model=model.name,
        method="gibbs-student-t",
        coefficients=model.coefficients,
        free=getattr(model, "free", None),
        observed=observed,
        constant=constant,
        settings=full,
        warnings=warn,
    )
