"""The ZIP fit's variants, by name: one sampler call each on columns in memory.

A variant takes the model, the columns (``v``, ``p``, ``q`` in per unit), their data rows
and times, and returns a :class:`~loadbayes.posterior.Posterior`; :func:`variant_of`
picks one from the options (errors in variables, then a drifting level, then the
likelihood), and :data:`VARIANTS` says which get the derived quantities and the
confounded-level warning afterwards. The chunked file (the Gaussian fit of a file read in
pieces) is the one path that never holds the columns: :mod:`.api` runs it on the Gram
matrix directly.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from loadbayes.fit.core import MAX_OBSERVED, accumulate, fit_gram
from loadbayes.fit.drift import fit_zip_drift
from loadbayes.fit.eiv import fit_zip_eiv
from loadbayes.fit.robust import fit_robust
from loadbayes.fit.zip.checks import add_derived, said_confounded
from loadbayes.io.errors import OptionError
from loadbayes.posterior import Posterior

__all__ = ["VARIANTS", "Variant", "variant_of"]


def _normal(model, cols, rows, t, *, priors, scheme, sampler, record, warnings, **_):
    """The paper's conjugate Gibbs sampler on the Gram matrix (``scheme``)."""
    return fit_gram(
        model, accumulate(model, [cols]), priors=priors or model.default_priors(),
        observed=cols if rows.size <= MAX_OBSERVED else None, settings=record,
        warnings=warnings, scheme=scheme, sampler=sampler,
    )  # fmt: skip


def _student_t(model, cols, rows, t, *, priors, nu, sampler, record, warnings, **_):
    """:func:`fit_robust` on the columns; flagged samples as 1-based data rows.

    ``rows`` are the data rows of the samples (of the file, or of the table); the result
    lists the flagged ones under ``flagged`` (by channel) and ``flagged_rows``, in the
    settings and in the JSON.
    """
    warnings = warnings + model.check(accumulate(model, [cols]))
    post = fit_robust(
        model,
        cols,
        priors=priors,
        nu=nu,
        observed=cols if rows.size <= MAX_OBSERVED else None,
        warnings=warnings,
        settings=record,
        sampler=sampler,
    )
    # 0-based sample indices -> 1-based data rows of the input
    by_channel = {ch: [int(rows[i]) for i in idx] for ch, idx in post.settings["flagged"].items()}
    st = post.settings
    st["flagged"] = by_channel
    st["flagged_rows"] = sorted({r for rs in by_channel.values() for r in rs})
    st["flagged_are"] = "1-based data rows of the input (header excluded)"
    post.extra_json.update(
        likelihood="student-t",
        flagged=list(st["flagged_rows"]),
        flagged_by_channel=dict(st["flagged"]),
        flag_rule=st["flag_rule"],
    )
    return post


def _drift(model, cols, rows, t, *, likelihood, sampler, record, warnings, v_noise=None, **_):
    """A level that drifts in time (:func:`loadbayes.fit.drift.fit_zip_drift`), with noise on V."""
    if likelihood != "normal":
        raise OptionError("a drifting level has a Gaussian likelihood only")
    cols, t, said = _without_glitches(cols, rows, t, record)
    warnings = warnings + said + model.check(accumulate(model, [cols]))
    return fit_zip_drift(cols, t, v0=model.v0, sampler=sampler, settings=record, warnings=warnings,
                         v_noise=v_noise)  # fmt: skip


def _without_glitches(cols, rows, t, record):
    """The columns less their glitches (``loadbayes cvr``'s rule), said and recorded.

    A spike in V or P, or a run of stuck readings, is one sample the drifting level
    cannot follow and the shares then answer to (a single +9% V spike moved a week's
    dP/dV from -8.9 to -0.4, issue 39): the drift fit leaves them out as ``loadbayes
    cvr`` does (:func:`loadbayes.fit.cvr_data.find_glitches`), counts them by kind and
    names their data rows (``settings["glitches"]``). Data without any are passed on as
    they are.
    """
    from loadbayes.fit.cvr_data import find_glitches

    gl = find_glitches(cols["v"], cols["p"], cols.get("q"))
    bad = gl.bad
    if not bad.any():
        return cols, t, []
    c = gl.counts()
    where = [int(r) for r in np.asarray(rows)[bad]]
    record["glitches"] = {**c, "rows": where}
    listed = ", ".join(map(str, where[:10])) + (", ..." if len(where) > 10 else "")
    said = (f"glitches left out of the fit: {c['spikes_v']} V spike(s), {c['spikes_p']} P "
            f"spike(s), {c['stuck']} stuck sample(s) ({c['left_out']} samples; data rows "
            f"{listed}; the rule of loadbayes cvr, docs/zip.md)")  # fmt: skip
    keep = ~bad
    return {k: np.asarray(x)[keep] for k, x in cols.items()}, np.asarray(t)[keep], [said]


def _eiv(model, cols, rows, t, *, v_noise, priors, sampler, record, warnings, **_):
    """Errors in variables: a latent true voltage (:mod:`loadbayes.fit.eiv`)."""
    if v_noise == "auto" and not model.with_q:
        raise OptionError(
            "v_noise='auto' needs Q as well as P: with P alone the noise on V is not "
            "identified (give the instrument's sd, e.g. v_noise=0.005)"
        )
    warnings = list(warnings) + model.check(accumulate(model, [cols]))
    return fit_zip_eiv(
        model, cols, v_noise=v_noise, priors=priors, sampler=sampler,
        observed=cols if cols["v"].size <= MAX_OBSERVED else None,
        settings=record, warnings=warnings,
    )  # fmt: skip


@dataclass(frozen=True)
class Variant:
    """One row of the table: the sampler call, and what follows it.

    ``derived``: the model's dP/dV, dQ/dV and the confounded-level warning are added to
    a table's fit (``"table"``), a file's (``"file"``), both, or neither (the drifting
    level has its own, per unit of the level).
    """

    fit: Callable[..., Posterior]
    derived: tuple[str, ...]


#: The variants, by name.
VARIANTS: dict[str, Variant] = {
    "normal": Variant(_normal, ("table", "file")),
    "student-t": Variant(_student_t, ("table", "file")),
    "drift": Variant(_drift, ()),
    "eiv": Variant(_eiv, ("table",)),
}


def variant_of(likelihood: str, level: str, v_noise: Any) -> str:
    """The variant of a ZIP fit's options: drift (noise on V or not), errors in variables."""
    if level == "drift":
        return "drift"
    if v_noise is not None:
        return "eiv"
    return "student-t" if likelihood == "student-t" else "normal"


def run(name: str, model, cols, rows, t, *, source: str, **options) -> Posterior:
    """Variant ``name`` on the columns, then its derived quantities for ``source``."""
    variant = VARIANTS[name]
    post = variant.fit(model, cols, rows, t, **options)
    if source in variant.derived:
        said_confounded(add_derived(post, model), model, cols, t)
    return post
