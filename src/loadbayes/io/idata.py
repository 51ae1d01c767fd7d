"""ArviZ's InferenceData groups built as xarray Datasets, without importing ArviZ.

A fit's NetCDF is ArviZ's format: one NetCDF group per InferenceData group, each an
``xarray.Dataset`` with ``chain`` and ``draw`` dimensions where it holds draws. Importing
ArviZ (with its plots, SciPy's stats and numba functions it compiles) cost 2.4 s of every
process that wrote or read one, most of a ``loadbayes predict``. Here the groups are
built as ``az.from_dict`` builds them (``arviz.data.base.dict_to_dataset``, ArviZ 0.23):
the same dimension names (``chain``, ``draw``, the given ones, else ``{name}_dim_{i}``),
the same integer coordinates from 0 where none are given, the same ``created_at`` and
``arviz_version`` attributes. :meth:`loadbayes.posterior.Posterior.to_arviz` wraps them in
an ``InferenceData``; ``to_netcdf`` writes them (:func:`loadbayes.io.atomic.write_groups`)
as ``InferenceData.to_netcdf`` would. ``tests/unit/test_netcdf_arviz.py`` holds them to
``az.from_dict``'s, group by group.
"""

from __future__ import annotations

import datetime
import functools
import importlib.metadata
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

__all__ = ["GROUP_ORDER", "dataset"]

#: InferenceData's order of the groups this package writes (``SUPPORTED_GROUPS``).
GROUP_ORDER = ("posterior", "posterior_predictive", "log_likelihood", "sample_stats",
               "observed_data", "constant_data")  # fmt: skip


@functools.cache
def _arviz_version() -> str:
    try:
        return importlib.metadata.version("arviz")
    except importlib.metadata.PackageNotFoundError:
        return "not installed"


def dataset(
    data: Mapping[str, Any],
    *,
    sampled: bool,
    dims: Mapping[str, Sequence[str]] | None = None,
    coords: Mapping[str, Any] | None = None,
    attrs: Mapping[str, Any] | None = None,
) -> Any:
    """One group's ``xarray.Dataset``, as ``az.dict_to_dataset`` makes it.

    Parameters
    ----------
    data : mapping of name to array
        The group's variables; with ``sampled`` each is ``(chain, draw, ...)`` (a 1-d
        array is one chain), else any shape (a scalar becomes one value).
    sampled : bool
        Draws (``chain``, ``draw`` leading) or data (``observed_data``, ``constant_data``).
    dims, coords : mapping, optional
        Names of each variable's dimensions after ``chain`` and ``draw``, and the
        coordinates of any dimension (``draw`` too); the others count from 0.
    attrs : mapping, optional
        Attributes after ``created_at`` and ``arviz_version``.
    """
    import xarray as xr

    dims, coords = dims or {}, coords or {}
    lead = ["chain", "draw"] if sampled else []
    variables = {}
    for name, value in data.items():
        ary = np.asarray(value)
        if sampled and ary.ndim < 2:
            ary = ary.reshape((1,) * (2 - ary.ndim) + ary.shape)
        elif not sampled and ary.ndim == 0:
            ary = ary.reshape(1)
        names = list(dims.get(name, []))
        rest = ary.shape[len(lead) :]
        names += [f"{name}_dim_{i}" for i in range(len(names), len(rest))]
        all_dims = lead + names
        axes = {
            d: xr.IndexVariable((d,), np.asarray(coords[d]) if d in coords else np.arange(n))
            for d, n in zip(all_dims, ary.shape, strict=True)
        }
        variables[name] = xr.DataArray(ary, coords=axes, dims=all_dims)
    made = {"created_at": datetime.datetime.now(datetime.UTC).isoformat(),
            "arviz_version": _arviz_version()}  # fmt: skip
    return xr.Dataset(data_vars=variables, attrs={**made, **dict(attrs or {})})
