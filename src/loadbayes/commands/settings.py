"""The settings objects of a command's options: what the library takes, built once.

A fit takes a :class:`~loadbayes.core.settings.SamplerSettings`, a
:class:`~loadbayes.core.settings.DataSpec` and, for the composite, a
:class:`~loadbayes.models.zip_motor.CompositeModel`; here are the decorators and
builders that turn a command's checked options into them (:func:`sampler_settings`,
:func:`data_spec`, :func:`fit_spec`, :func:`composite_model` through
:data:`COMPOSITE_FLAGS`). The options themselves are declared in :mod:`.options`.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any

import click

_SAMPLER_KEYS = ("draws", "burn", "chains", "thin", "seed", "init", "hdi_prob")


def sampler_settings(
    *,
    draws: int = 40_000,
    burn: int = 5_000,
    init: bool = True,
    draws_help: str = "Iterations per chain including burn-in (the paper's M).",
    burn_help: str = "Leading iterations discarded (the paper's m).",
    draws_min: int = 1,
    burn_min: int = 0,
    adjust: Callable[[dict[str, Any], dict[str, Any]], dict[str, Any]] | None = None,
):
    """--draws --burn --chains --thin --seed [--init] --hdi-prob, built into one object.

    The command receives ``sampler``, a checked
    :class:`~loadbayes.core.settings.SamplerSettings`, instead of the loose options; a
    burn-in not below the draws is one line naming both options. ``adjust``, if given,
    is called with the sampler's values and the command's other options before that
    check and returns the values to use (``fit zip --by`` has its own defaults).
    """

    def deco(func):
        @functools.wraps(func)
        def wrapper(*args, **kwargs):
            from loadbayes.commands.output import UserError
            from loadbayes.core.settings import SamplerSettings

            values = {k: kwargs.pop(k) for k in _SAMPLER_KEYS if k in kwargs}
            if adjust is not None:
                values = adjust(values, kwargs)
            if values["burn"] >= values["draws"]:
                raise UserError(
                    f"--burn ({values['burn']}) must be smaller than --draws ({values['draws']})"
                )
            kwargs["sampler"] = SamplerSettings(**values)
            return func(*args, **kwargs)

        opts = [
            click.option(
                "--draws",
                type=click.IntRange(min=draws_min),
                default=draws,
                show_default=True,
                help=draws_help,
            ),
            click.option(
                "--burn",
                type=click.IntRange(min=burn_min),
                default=burn,
                show_default=True,
                help=burn_help,
            ),
            click.option("--chains", type=click.IntRange(min=1), default=4, show_default=True),
            click.option("--thin", type=click.IntRange(min=1), default=1, show_default=True),
            click.option("--seed", type=int, default=0, show_default=True),
        ]
        if init:
            opts.append(
                click.option(
                    "--init",
                    type=click.Choice(["prior", "dispersed"]),
                    default="prior",
                    show_default=True,
                    help="Start from a prior draw (the paper) or scattered around LS.",
                )
            )
        opts.append(
            click.option(
                "--hdi-prob",
                type=click.FloatRange(0, 1, min_open=True, max_open=True),
                default=0.95,
                show_default=True,
            )
        )
        for opt in reversed(opts):
            wrapper = opt(wrapper)
        return wrapper

    return deco


def data_spec(*names: str):
    """Hand the command ``spec``: one DataSpec of the options ``names``, in their place.

    The options are declared by :func:`.options.data_options`, :func:`.options.nominal_options`,
    :func:`.options.accept_units_option` or the command; the
    :class:`~loadbayes.core.settings.DataSpec` goes to the fit as it is. Only options
    whose every value makes a valid ``DataSpec`` belong here (``drop_invalid``,
    ``accept_units``): the CLI checks the others in its own words at points of the run
    that a check when the command starts would move (the V0 check comes after the
    file's first chunk, the base check after the "P0 not given" note), so ``fit zip``
    and ``fit exp`` still hand their columns, bases and nominal point to the fit one
    by one (a fit's keywords changed from their defaults override its ``spec``).
    """

    def deco(func):
        @functools.wraps(func)
        def wrapper(*args, **kwargs):
            from loadbayes.core.settings import DataSpec

            kwargs["spec"] = DataSpec(**{k: kwargs.pop(k) for k in names})
            return func(*args, **kwargs)

        return wrapper

    return deco


def fit_spec(**values: Any):
    """The fit's DataSpec of a command's checked options (``p0="auto"`` is None).

    A bad base or V0 is refused here in the words the fit used when it took them loose
    (``--v-base must be positive, got -1.0``), just before the fit that used to say so.
    """
    from loadbayes.commands.output import UserError
    from loadbayes.core.settings import DataSpec

    for name in ("v_base", "s_base"):
        base = values.get(name)
        if base is not None and not (math.isfinite(base) and base > 0):
            raise UserError(f"--{name.replace('_', '-')} must be positive, got {base}")
    v0 = values.get("v0", 1.0)
    if not (math.isfinite(v0) and v0 > 0):
        raise UserError(f"v0 must be positive, got {v0}")
    for name in ("p0", "q0"):
        if values.get(name) == "auto":
            values[name] = None
    return DataSpec(**values)


#: The composite model's fields as ``fit composite`` spells them: the one table from
#: flags to :class:`~loadbayes.models.zip_motor.CompositeModel` (its errors name the
#: flag through it).
COMPOSITE_FLAGS = {
    "f_hz": "--f-hz",
    "torque": "--torque",
    "steps": "--steps",
    "window_s": "--window-s",
    "shares": "--shares",
    "noise": "--noise",
    "likelihood": "--likelihood",
    "nu": "--nu",
    "priors": "--prior",
    "prior": "--prior",
    "h_max": "--h-max",
}


def composite_model(**fields: Any) -> Any:
    """The composite model of the flags' values; its refusal worded with the flags."""
    from loadbayes.io.errors import OptionError
    from loadbayes.models.base import ModelOptionError
    from loadbayes.models.zip_motor import CompositeModel

    try:
        return CompositeModel(**fields)
    except ModelOptionError as exc:
        typed = ("priors", "torque")
        first = next((f for f in typed if exc.template.startswith(f"{{{f}}} ")), None)
        if first is not None:  # a value typed badly: click's one-line form, as it parses them
            rest = exc.template[len(first) + 3 :]
            raise click.BadParameter(
                ModelOptionError(rest).worded(COMPOSITE_FLAGS), param_hint=COMPOSITE_FLAGS[first]
            ) from None
        raise OptionError(exc.worded(COMPOSITE_FLAGS)) from None  # one line, exit 2


#: A model of parts' fields as ``fit composite`` spells them.
PARTS_FLAGS = {"f_hz": "--f-hz", "priors": "--prior", "negative_sequence": "--negative-sequence",
               "noise": "--noise", "rho_max": "--rho-max"}  # fmt: skip


def parts_model(name: str, **fields: Any) -> Any:
    """The model of parts ``name`` (``slm``, ``cmld-lite``); its refusal worded with flags."""
    from loadbayes.commands.output import UserError
    from loadbayes.models.base import ModelOptionError
    from loadbayes.models.dynamic import dynamic_model

    try:
        return dynamic_model(name, **fields)
    except ModelOptionError as exc:
        raise UserError(exc.worded(PARTS_FLAGS)) from None


#: The options of ``--model zip+motor`` alone, by parameter name.
ZIP_MOTOR_ONLY = {"torque": "--torque", "steps": "--steps", "shares": "--shares",
                  "likelihood": "--likelihood", "window_s": "--window-s",
                  "nu": "--nu"}  # fmt: skip


def check_model_flags(model_name: str, *, negative_sequence: str, plot: bool) -> None:
    """Refuse, in one line, a flag the chosen ``--model`` has no use for."""
    from loadbayes.commands.output import UserError

    if model_name == "zip+motor":
        if negative_sequence != "auto":
            raise UserError("--negative-sequence is an option of --model slm and cmld-lite")
        return
    ctx = click.get_current_context()
    if model_name == "auto" and ctx.get_parameter_source("noise") not in (
        None, click.core.ParameterSource.DEFAULT):  # fmt: skip
        raise UserError("--noise needs a named --model (zip+motor, slm or cmld-lite), not auto")
    for name, flag in ZIP_MOTOR_ONLY.items():
        if ctx.get_parameter_source(name) not in (None, click.core.ParameterSource.DEFAULT):
            raise UserError(f"{flag} is an option of --model zip+motor, not {model_name}")
    if plot:
        raise UserError(f"--plot draws zip+motor fits only so far, not {model_name}")


def named_model(name: str, *, f_hz: float, priors: dict, negative_sequence: str,
                noise: str = "white", rho_max: float | None = None,
                **zip_motor: Any) -> Any:  # fmt: skip
    """``fit composite --model NAME``'s model (None for ``auto``: chosen on the events)."""
    from loadbayes.commands.output import UserError

    if rho_max is not None and (name not in ("slm", "cmld-lite") or noise != "ar1"):
        raise UserError("--rho-max is an option of --noise ar1 with --model slm or cmld-lite")
    if name == "auto":
        if priors:
            raise UserError("--prior needs a named --model (slm, cmld-lite or zip+motor)")
        return None
    if name != "zip+motor":
        bound = {} if rho_max is None else {"rho_max": rho_max}
        return parts_model(name, f_hz=f_hz, priors=priors, negative_sequence=negative_sequence,
                           noise=noise, **bound)  # fmt: skip
    return composite_model(f_hz=f_hz, priors=priors, noise=noise, **zip_motor)
