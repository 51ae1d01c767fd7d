"""The pooled (hierarchical) ZIP model of a fleet, sampled by Gibbs from per-bus statistics.

Model (``--pool class``; the full statement and conditionals are in ``docs/fleet.md``).
For bus ``b`` of class ``c`` with ``n_b`` rows, coefficient vector
``theta_b = (a1, a2)`` or ``(a1, a2, a4, a5)`` (``d = 2`` or 4) and channels P (and Q)::

    r_ch = Z theta_b,ch + e,  e ~ N(0, 1 / tau_b,ch)       (the ZIP regression)
    theta_b ~ N(mu_c, Sigma_c)
    mu_c ~ N(m0, S0),  Sigma_c ~ inverse-Wishart(nu0, Psi0_c),  tau_b,ch ~ Gamma(a0, b0)
    Psi0_c = lam_c (nu0 - d - 1) I,  lam_c ~ Gamma(1/2, 1 / (2 A^2))   (A: spread_scale)

Every conditional is conjugate and needs the data only through each bus's ``Z'Z``,
``Z'r``, ``r'r`` and ``n`` (:class:`~loadbayes.fleet.stats.FleetStats`), so a sweep
costs O(buses), whatever the rows. One sweep, with ``J_b = diag_ch(tau_ch Z'Z)`` and
``u_b = (tau_ch Z'r_ch)_ch``:

1. ``mu_c | Sigma_c, tau, data`` with every ``theta_b`` integrated out: normal with
   precision ``S0^-1 + sum_b (Sigma^-1 - Sigma^-1 L_b^-1 Sigma^-1)`` and linear term
   ``S0^-1 m0 + sum_b Sigma^-1 L_b^-1 u_b``, ``L_b = Sigma_c^-1 + J_b``;
2. ``theta_b | mu_c, Sigma_c, tau_b ~ N(L_b^-1 h_b, L_b^-1)``, ``h_b = Sigma_c^-1 mu_c +
   u_b`` (P and Q coupled through Sigma_c). Steps 1-2 draw ``(mu, theta)`` jointly;
3. ``tau_b,ch | theta_b ~ Gamma(a0 + n_b / 2, b0 + SSR_ch(theta_b) / 2)``;
4. ``Sigma_c | theta, mu_c ~ IW(nu0 + n_c, Psi0_c + sum_b (theta_b - mu_c)(theta_b - mu_c)')``;
5. ``lam_c | Sigma_c ~ Gamma(1/2 + d nu0 / 2, 1 / (2 A^2) + (nu0 - d - 1) tr(Sigma_c^-1) / 2)``
   (skipped, ``Psi0`` fixed, with ``spread_scale=None``: the model until 2026-11-29).

Why the scale is learned (issue 40): along the curvature ``a1 - 2 a2 + a3`` no bus on a
narrow band sees its class's spread, along the slope ``2 a1 + a2`` every bus does; one
scale a class carries what the slope shows to the curvature. With ``Psi0`` fixed at a
spread of 0.1 the shares a1, a2 covered 83% at a true spread of 0.2 (docs/fleet.md).

Why step 1 integrates: ZIP data pin each bus's coefficients down along one direction
only (``a1 (x^2 - 1) + a2 (x - 1)`` is close to ``(2 a1 + a2)(x - 1)`` on a narrow band),
so along the other the bus coefficients and the class mean are strongly coupled, and
alternating ``mu | theta`` and ``theta | mu`` crawls (an ESS of 6 in 4 x 1,000 draws was
measured on a 60-bus fleet). The collapsed draw removes that coupling.

Steps 1-3 run in compiled loops over buses; 4 is a few small matrices per class.
Each chain has its own generator (``SeedSequence(seed).spawn(chains)``) from which every
sweep draws, in a fixed order, the normals of ``mu``, the bus normals, the bus gammas,
then the Bartlett variates of ``Sigma``: the draws depend on the seed only, not on which
worker runs the chain.

Shrinkage of a bus (reported per bus): with ``theta_hat`` its own least-squares estimate,
``|E theta_b - theta_hat|_J / (|E theta_b - theta_hat|_J + |E theta_b - E mu_c|_J)``,
distances measured in the bus's own data precision ``J_b`` (at the posterior mean of
``tau``): 0 where the bus stays where its own data put it, 1 where it sits on its class
mean. The metric matters: along the a1-a2 ridge a bus's data say little, and a move
along it is no departure from them (a Euclidean ratio called data-rich buses 80%
shrunk because of such moves). A bus whose own data cannot identify its coefficients
(no voltage spread, as many distinct voltages as coefficients or fewer) has shrinkage 1.

Prior-driven split (``prior_sd_ratio``, ``prior_driven`` per bus and channel, issue 40):
along the curvature ``a1 - 2 a2 + a3`` the bus's own data sd ``s_d`` against its class
spread's ``s_c``; ``s_d / sqrt(s_d^2 + s_c^2)`` above ``PRIOR_DRIVEN`` (0.7) says the
split of a1, a2 is the class's, in the bus's warnings (:func:`_curvature_ratio`).

Its length is one idea: the pooled model's Gibbs sweep, derived above (60 lines
of docstring), with the chains it runs and their summary; the compiled loops over
buses are in :mod:`loadbayes.fleet.hier_kernels`.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pandas as pd

from loadbayes.core.parallel import chain_seeds
from loadbayes.core.settings import SamplerSettings
from loadbayes.fleet.diagnostics import summarize
from loadbayes.fleet.hier_kernels import (
    _bartlett,
    _bus_sweep,
    _class_sums,
    _factor,
    _mu_draw,
    _mu_terms,
    _scale_moves_all,
)
from loadbayes.fleet.stats import FleetStats
from loadbayes.fleet.summary import PRIOR_DRIVEN, failed_rows, stat_rows
from loadbayes.inference.chain import Chain, Field, kept_count
from loadbayes.io.errors import DataError
from loadbayes.models.zip import ZIPModel

__all__ = [
    "ChainState",
    "HierData",
    "StoredDraws",
    "HierPrior",
    "chain_seeds",
    "class_convergence",
    "prepare",
    "run_chain",
    "summarize_chains",
]

#: Condition number of a bus's scaled Z'Z above which its own data do not identify it.
_ILL = 1e12


@dataclass(frozen=True)
class HierPrior:
    """Hyperpriors. Defaults: weak on the class means, each class's spread learned.

    Attributes
    ----------
    mean_sd : float
        ``mu_c ~ N(0, mean_sd^2 I)``.
    nu0 : float or None
        Inverse-Wishart degrees of freedom (default ``d + 2``, the weakest with a mean).
    spread : float
        With ``spread_scale`` None, the prior guess of the within-class sd of each
        coefficient: ``Psi0 = spread^2 (nu0 - d - 1) I``, so that ``E Sigma_c = spread^2
        I`` (the default until 2026-11-29).
    tau_shape, tau_rate : float
        ``tau_b ~ Gamma(shape, rate)`` (as the single-bus fits).
    spread_scale : float or None
        With a value ``A``, each class's scale is learned: ``Psi0_c = lam_c (nu0 - d - 1)
        I`` with ``lam_c ~ Gamma(1/2, rate 1 / (2 A^2))`` (``sqrt(lam_c)``, the class's
        typical spread, half-normal of scale ``A``; Huang and Wand 2013 with one scale a
        class), drawn each sweep from ``Gamma(1/2 + d nu0 / 2, 1 / (2 A^2) + (nu0 - d - 1)
        tr(Sigma_c^-1) / 2)``; ``spread`` is then only where the chains start. With None,
        ``Psi0`` is fixed at ``spread``. Why learned (default ``A`` = 0.5): the data fix a
        class's spread along the slope ``2 a1 + a2`` and barely along the curvature; a
        fixed ``Psi0`` left the latter to one prior value, and on issue 40's fleets the
        shares a1, a2 covered 83% at a true spread of 0.2 (docs/fleet.md).
    """

    mean_sd: float = 10.0
    nu0: float | None = None
    spread: float = 0.1
    tau_shape: float = 1e-3
    tau_rate: float = 1e-9
    spread_scale: float | None = 0.5

    def matrices(self, d: int) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
        """``m0``, ``S0^-1``, ``nu0``, ``Psi0`` for dimension ``d``."""
        nu0 = float(self.nu0) if self.nu0 is not None else d + 2.0
        if nu0 <= d - 1:
            raise ValueError(f"nu0 must exceed d - 1 = {d - 1}, got {nu0}")
        psi = self.spread**2 * max(nu0 - d - 1.0, 1.0) * np.eye(d)
        return np.zeros(d), np.eye(d) / self.mean_sd**2, nu0, psi


@dataclass(frozen=True)
class HierData:
    """What the sampler needs of the buses it pools (per-bus statistics, class codes).

    Per bus and channel, ``y`` is the measured P (Q) when its nominal value is sampled,
    or ``P / P0`` when P0 is given (then ``s`` stays 1 and ``scale`` is the given P0);
    ``X = [1, z1, z2]``.
    """

    buses: np.ndarray
    class_names: list[str]
    cls: np.ndarray  # int64 (B,)
    n: np.ndarray  # (B,)
    ztz: np.ndarray  # (B, 2, 2)
    theta_ls: np.ndarray  # (B, nch, 2): own least-squares shares at the LS level
    identified: np.ndarray  # bool (B,): own data identify the coefficients
    params: tuple[str, ...]  # coefficient names in theta order
    taus: tuple[str, ...]
    warnings: list[str]
    g3: np.ndarray  # (B, 3, 3): X'X
    xy: np.ndarray  # (B, nch, 3): X'y
    beta_ls: np.ndarray  # (B, nch, 3): a least-squares solution of y on X
    ssr_min: np.ndarray  # (B, nch): its residual sum of squares
    fixed: np.ndarray  # bool (B, nch): the nominal value is given
    level: np.ndarray  # (B, nch): the LS level of y at V0 (1 where fixed): the start
    scale: np.ndarray  # (B, nch): y units -> reported P0 (the given P0, or 1)
    v0: float = 1.0

    @property
    def nominals(self) -> tuple[str, ...]:
        """Names of the nominal values: ``p0`` (and ``q0``)."""
        return ("p0", "q0")[: self.xy.shape[1]]


def _known_nominal(stats: FleetStats, model: ZIPModel) -> tuple[FleetStats, dict[int, list[str]]]:
    """Per-bus statistics in per unit of each bus's own P0 (Q0) when they are ``auto``.

    The pooled model is on the shares, so every bus needs a nominal power. With ``auto``
    each bus's P0 is its least-squares level at V0 (the coefficient of the constant in
    ``P = P0 + d1 (x^2 - 1) + d2 (x - 1)``), held fixed: its uncertainty is not carried
    into the pooled posterior (it is small next to the shares' wherever V moved, since
    P0 is an interpolation to V0, not an extrapolation). The Gram entries of
    ``r = P / P0 - 1`` follow exactly from those of ``P``: ``z'r = z'P / P0 - z'1`` and
    ``r'r = P'P / P0^2 - 2 1'P / P0 + n``.
    """
    chans = [("p", model.p0)] + ([("q", model.q0)] if model.with_q else [])
    if all(nom != "auto" for _, nom in chans):
        return stats, {}
    names = list(stats.names)
    one, z1, z2 = (names.index(c) for c in ("1", "z1", "z2"))
    g = stats.gram.copy()
    lo, hi = stats.col_min.copy(), stats.col_max.copy()
    notes: dict[int, list[str]] = {}
    new_names = list(names)
    for ch, nom in chans:
        j = names.index(ch if nom == "auto" else f"r{ch}")
        if nom != "auto":
            continue
        for b in range(stats.buses.size):
            a = g[b][np.ix_([one, z1, z2], [one, z1, z2])]
            rhs = g[b][[one, z1, z2], j]
            coef = np.linalg.lstsq(a, rhs, rcond=None)[0] if stats.n[b] else np.zeros(3)
            level = float(coef[0]) if abs(coef[0]) > 0 else float(rhs[0] / max(stats.n[b], 1))
            if not (np.isfinite(level) and level != 0):
                level = 1.0
            pp, p1 = g[b, j, j], g[b, one, j]
            row = g[b, :, j] / level - g[b, :, one]
            g[b, :, j] = row
            g[b, j, :] = row
            g[b, j, j] = pp / level**2 - 2.0 * p1 / level + stats.n[b]
            ends = sorted((lo[b, j] / level - 1.0, hi[b, j] / level - 1.0))
            lo[b, j], hi[b, j] = ends
            notes.setdefault(b, []).append(f"{ch}0 = {level:.6g} estimated (least squares at V0)")
        new_names[j] = f"r{ch}"
    out = FleetStats(
        tuple(new_names), stats.buses, stats.classes, g, stats.n, lo, hi, stats.bad,
        stats.n_dropped,
    )  # fmt: skip
    return out, notes


def prepare(stats: FleetStats, model: ZIPModel) -> tuple[HierData, pd.DataFrame]:
    """Split the fleet into buses to pool and warning rows for buses that cannot be.

    A bus is pooled if it has at least 3 rows; without voltage spread it is pooled with
    a warning (its coefficients then come from its class). Rows beyond that are refused
    for the same reasons as a single-bus fit (:meth:`ZIPModel.check`).
    """
    # The refusals and warnings of one bus, on its statistics per unit of its LS level
    # (a bus of 3 rows is pooled: its shares come mostly from its class).
    unit, notes = _known_nominal(stats, model)
    checker = ZIPModel(v0=model.v0, p0=1.0, q0=1.0, with_q=model.with_q) if notes else model
    iz = stats.names.index("z2")
    keep, warn, failed = [], [], []
    for i in range(stats.buses.size):
        if stats.bad[i]:
            failed.append((i, "values too large: their products overflow float64"))
            continue
        if stats.n[i] < 3:
            failed.append((i, f"not fitted: {stats.n[i]} rows, fewer than 3"))
            continue
        w = []
        if stats.col_max[i, iz] == stats.col_min[i, iz]:
            w.append("voltage has no spread: the coefficients come from the class alone")
        else:
            try:
                w = checker.check(unit.bus_gram(i))
            except DataError as exc:
                failed.append((i, f"not fitted: {exc.message}"))
                continue
        keep.append(i)
        warn.append(" | ".join(w))
    idx = np.array(keep, dtype=np.int64)
    arrays = _regressions(stats.subset(idx), model)
    ztz = arrays["g3"][:, 1:, 1:]
    scale = np.sqrt(np.maximum(np.einsum("bii->bi", ztz), 1e-300))
    with np.errstate(divide="ignore", invalid="ignore"):
        cond = np.linalg.cond(ztz / (scale[:, :, None] * scale[:, None, :]))
    identified = np.isfinite(cond) & (cond < _ILL)
    labels = np.array(["all" if c is None else str(c) for c in stats.classes[idx]], dtype=object)
    class_names, cls = np.unique(labels.astype(str), return_inverse=True)
    data = HierData(
        stats.buses[idx], [str(c) for c in class_names], cls.astype(np.int64),
        stats.n[idx].astype(float),
        np.ascontiguousarray(ztz), identified=identified, params=tuple(model.free),
        taus=tuple(b.tau_name for b in model.blocks), warnings=warn, v0=float(model.v0),
        **arrays,
    )  # fmt: skip
    fi = np.array([i for i, _ in failed], dtype=np.int64)
    rows = failed_rows(stats.buses[fi], stats.classes[fi], stats.n[fi], [r for _, r in failed])
    return data, rows


def _regressions(stats: FleetStats, model: ZIPModel) -> dict[str, np.ndarray]:
    """Per bus and channel: the regression of ``y`` on ``X = [1, z1, z2]`` (HierData's arrays).

    ``y`` is P (Q) when its nominal value is ``auto`` (then sampled), else ``P / P0 =
    r + 1`` from the Gram column ``r = P / P0 - 1``: ``X'y = X'r + X'1`` and ``y'y = r'r +
    2 1'r + n``, exactly.
    """
    names = list(stats.names)
    ix = [names.index(c) for c in ("1", "z1", "z2")]
    one = ix[0]
    g = stats.gram
    g3 = g[:, ix][:, :, ix]
    chans = [("p", model.p0)] + ([("q", model.q0)] if model.with_q else [])
    xy, yy, fixed, scale = [], [], [], []
    for ch, nom in chans:
        j = names.index(ch if nom == "auto" else f"r{ch}")
        if nom == "auto":
            xy.append(g[:, ix, j])
            yy.append(g[:, j, j])
        else:
            xy.append(g[:, ix, j] + g[:, ix, one])
            yy.append(g[:, j, j] + 2.0 * g[:, one, j] + g[:, one, one])
        fixed.append(np.full(stats.buses.size, nom != "auto"))
        scale.append(np.full(stats.buses.size, 1.0 if nom == "auto" else float(nom)))
    xy_a = np.stack(xy, axis=1)  # (B, nch, 3)
    beta = np.einsum("bij,bcj->bci", np.linalg.pinv(g3), xy_a)
    ssr_min = np.maximum(np.stack(yy, axis=1) - np.einsum("bci,bci->bc", beta, xy_a), 0.0)
    fixed_a = np.stack(fixed, axis=1)
    n = np.maximum(stats.n.astype(float), 1.0)[:, None]
    level = np.where(fixed_a, 1.0, beta[:, :, 0])
    bad = ~np.isfinite(level) | (level == 0.0)
    level = np.where(bad, xy_a[:, :, 0] / n, level)  # the mean of y
    level = np.where(~np.isfinite(level) | (level == 0.0), 1.0, level)
    ztz = g3[:, 1:, 1:]
    ztr = xy_a[:, :, 1:] / level[:, :, None] - g3[:, None, 1:, 0]
    theta_ls = np.einsum("bij,bcj->bci", np.linalg.pinv(ztz), ztr)
    return {
        "theta_ls": np.ascontiguousarray(theta_ls),
        "g3": np.ascontiguousarray(g3),
        "xy": np.ascontiguousarray(xy_a),
        "beta_ls": np.ascontiguousarray(beta),
        "ssr_min": np.ascontiguousarray(ssr_min),
        "fixed": np.ascontiguousarray(fixed_a),
        "level": np.ascontiguousarray(level),
        "scale": np.ascontiguousarray(np.stack(scale, axis=1)),
    }


def _draw_mu(gen, s0_inv, s0_inv_m0, prec_data, lin_data):
    """``mu_c ~ N(prec^-1 rhs, prec^-1)`` for every class."""
    z = gen.standard_normal(lin_data.shape)
    mu = np.empty_like(lin_data)
    if not _mu_draw(s0_inv, s0_inv_m0, prec_data, lin_data, z, mu):
        raise np.linalg.LinAlgError("the class means' precision is not positive definite")
    return mu


def _draw_sigma(gen, nu, psi):
    """Inverse-Wishart draws, one per class (Bartlett decomposition of the Wishart inverse).

    ``Sigma ~ IW(nu, Psi)`` iff ``Sigma^-1 ~ W(nu, Psi^-1)``; with ``Psi^-1 = C C'``,
    ``Sigma^-1 = C A A' C'``, ``A`` lower triangular, ``A_ii^2 ~ chi2(nu - i)``,
    ``A_ij ~ N(0, 1)`` below the diagonal.
    """
    ncls, d, _ = psi.shape
    chi = gen.chisquare(nu[:, None] - np.arange(d)[None, :])
    nrm = gen.standard_normal((ncls, d, d))
    sigma, sig_inv = np.empty_like(psi), np.empty_like(psi)
    if not _bartlett(chi, nrm, np.ascontiguousarray(psi), sigma, sig_inv):
        raise np.linalg.LinAlgError("a class's inverse-Wishart scale is not positive definite")
    return sigma, sig_inv


#: Log-sd of the proposals of the scale moves, and the tries per direction and sweep.
_SCALE_STEP = 0.25
_SCALE_TRIES = 2


def _directions(nch: int) -> np.ndarray:
    """The scale moves' directions: per channel, along and across the ZIP ridge.

    On a narrow band the data fix ``2 a1 + a2`` (the slope dP/dV) and barely ``a1 - 2 a2``
    (the curvature); the spread of a class along the second direction is what the
    centred Gibbs steps move slowly.
    """
    out = np.zeros((2 * nch, 2 * nch))
    for ch in range(nch):
        out[2 * ch, 2 * ch : 2 * ch + 2] = (2.0, 1.0)
        out[2 * ch + 1, 2 * ch : 2 * ch + 2] = (1.0, -2.0)
    return out / np.sqrt(5.0)


def _scale_moves(gen, data, nu0, psi0, mu, theta, s, t, sigma, sig_inv, dirs, acc_a, acc_b):
    """Metropolis moves that stretch a class's spread along a direction (parameter expansion).

    The map ``theta_b -> mu_c + C (theta_b - mu_c)``, ``Sigma_c -> C Sigma_c C'`` with
    ``C = I + (c - 1) v v'`` leaves the normal prior's exponent unchanged; with its
    Jacobian ``c^(B + d + 1)`` and the densities' determinants the target changes by
    ``c^-nu0 exp(-tr(Psi0 (C^-1 Sigma^-1 C^-1 - Sigma^-1)) / 2)`` times the likelihood
    ratio of the buses (quadratic in ``c``, :func:`_scale_terms`). ``log c`` is proposed
    symmetrically (the Haar measure of the scalings), so this is a valid Metropolis step
    on the joint state (Liu and Sabatti 2000). It moves the spread and every bus of the
    class at once, which the centred Gibbs steps do only slowly when the buses' own data
    say little (the funnel of hierarchical models).
    """
    ncls = mu.shape[0]
    z = np.empty((len(dirs), _SCALE_TRIES, ncls))
    uni = np.empty((len(dirs), _SCALE_TRIES, ncls))
    for k in range(len(dirs)):  # the stream's order: per direction and try, normals, uniforms
        for r in range(_SCALE_TRIES):
            z[k, r] = gen.standard_normal(ncls)
            uni[k, r] = gen.random(ncls)
    # (the moves draw nothing themselves: drawn first, the chain's stream is the same)
    _scale_moves_all(data.cls, data.g3, data.xy, s, t, theta, mu, dirs, psi0, nu0, _SCALE_STEP,
                     sigma, sig_inv, acc_a, acc_b, z, uni, np.empty(ncls))  # fmt: skip
    return sigma, sig_inv


@dataclass
class ChainState:
    """Where a chain stopped: enough to continue it with the same draws as one long run."""

    generator: dict
    mu: np.ndarray
    sigma: np.ndarray
    sig_inv: np.ndarray
    theta: np.ndarray
    s: np.ndarray
    t: np.ndarray
    sweeps: int
    lam: np.ndarray | None = None  # the classes' learned scales (``spread_scale``)


#: Kept draws written to disk per block (``store``): the memory a chain holds.
STORE_BLOCK = 100


class StoredDraws:
    """Draws of one variable of a chain in a NetCDF file, read by slices (``x[:, b0:b1]``)."""

    def __init__(self, path: str, name: str, shape: tuple[int, ...]) -> None:
        self.path, self.name, self.shape = path, name, shape

    def __getitem__(self, key):
        # h5py, not h5netcdf: opening through h5netcdf (its dimensions) cost more than the
        # read itself, at one open per variable, chain and batch of buses
        import h5py

        with h5py.File(self.path, "r") as f:
            return np.asarray(f[self.name][key])


class _Store:
    """A chain's bus-level draws streamed to a NetCDF-4 file in blocks of draws.

    Chunks are (block, 512 buses, k): the summary reads all draws of a batch of buses.
    """

    def __init__(self, path: str, kept: int, nb: int, shapes: dict[str, int]) -> None:
        import h5netcdf

        self.path = path
        self.f = h5netcdf.File(path, "w")
        self.f.dimensions = {"draw": kept, "bus": nb, **{f"{k}_dim": n for k, n in shapes.items()}}
        self.vars = {
            k: self.f.create_variable(
                k, ("draw", "bus", f"{k}_dim"), np.float32,
                chunks=(max(1, min(STORE_BLOCK, kept)), max(1, min(512, nb)), n),
            )
            for k, n in shapes.items()
        }  # fmt: skip
        self.shapes = {k: (kept, nb, n) for k, n in shapes.items()}

    def write(self, start: int, blocks: dict[str, np.ndarray], count: int) -> None:
        for k, buf in blocks.items():
            self.vars[k][start : start + count] = buf[:count]

    def close(self) -> dict[str, StoredDraws]:
        self.f.close()
        return {k: StoredDraws(self.path, k, shp) for k, shp in self.shapes.items()}


@dataclass
class FleetChainDraws:
    """Kept draws of one chain, and its state at the end.

    ``theta`` (draw, bus, d), ``tau`` (draw, bus, nch: precision per unit of P0) and
    ``p0`` (draw, bus, nch: the nominal P, Q) as float32 (half the memory of a large
    fleet; far below Monte Carlo error); ``mu`` (draw, class, d) and ``sigma`` (draw,
    class, d, d) as float64.
    """

    theta: np.ndarray
    tau: np.ndarray
    mu: np.ndarray
    sigma: np.ndarray
    p0: np.ndarray | None = None
    state: ChainState | None = None


def run_chain(
    start: np.random.SeedSequence | ChainState,
    data: HierData,
    prior: HierPrior,
    sampler: SamplerSettings,
    *,
    sweeps: int | None = None,
    store: str | None = None,
    stop: threading.Event | None = None,
) -> FleetChainDraws:
    """Run one Gibbs chain of the pooled model (see the module notes).

    A new chain (``start`` a seed) runs ``sampler.draws`` sweeps and keeps those after
    ``sampler.burn`` (every ``thin``-th); a chain continued from its :class:`ChainState`
    runs ``sweeps`` more (default ``draws - burn``) and keeps them all (thinned). A chain
    run in two calls gives the same draws as one call of the same total length.
    With ``store`` (a file path), the bus-level draws go to that NetCDF file in blocks of
    :data:`STORE_BLOCK` draws (the chain then holds one block in memory) and the result's
    ``theta``, ``tau``, ``p0`` are :class:`StoredDraws`; the draws are the same.
    The chain checks ``stop`` (and a signal's stop request) every sweep and raises
    :class:`~loadbayes.core.parallel.ChainsStopped` when it is set (chains run in threads).
    """
    nb = data.buses.size
    nch = data.xy.shape[1]
    d = 2 * nch
    ncls = len(data.class_names)
    m0, s0_inv, nu0, psi0 = prior.matrices(d)
    nc = np.bincount(data.cls, minlength=ncls).astype(float)
    shape = prior.tau_shape + 0.5 * data.n
    # the gamma prior is on the precision per unit of P0 (as one bus's fit); on the
    # precision of y it is Gamma(a0, b0 level^2), the level being the LS one
    rate = prior.tau_rate * data.level**2
    if isinstance(start, ChainState):
        gen = np.random.Generator(np.random.PCG64())
        gen.bit_generator.state = start.generator
        mu, sigma, sig_inv = start.mu.copy(), start.sigma.copy(), start.sig_inv.copy()
        theta, s, t = start.theta.copy(), start.s.copy(), start.t.copy()
        lam = None if start.lam is None else start.lam.copy()
        total = sampler.draws - sampler.burn if sweeps is None else sweeps
        burn, done = 0, start.sweeps
    else:
        gen = np.random.default_rng(start)
        lam = None
        # Start: class means scattered about 0, Sigma at its prior mean, P0 at its LS
        # level, the noise at 0.1 per unit; the bus coefficients are drawn first.
        mu = gen.normal(0.0, 0.5, (ncls, d))
        sigma = np.broadcast_to(psi0 / max(nu0 - d - 1.0, 1.0), (ncls, d, d)).copy()
        sig_inv = np.linalg.inv(sigma)
        theta = np.zeros((nb, d))
        s = data.level.copy()
        t = 100.0 / data.level**2
        total, burn, done = sampler.draws, sampler.burn, 0
    sums = np.zeros((ncls, d))
    scatter = np.zeros((ncls, d, d))
    prec_data = np.zeros((ncls, d, d))
    lin_data = np.zeros((ncls, d))
    chol = np.empty((nb, d, d))
    u = np.empty((nb, d))
    ok = np.empty(nb, np.bool_)
    s0_inv_m0 = s0_inv @ m0
    gshape = np.ascontiguousarray(np.broadcast_to(shape[:, None], (nb, nch)))
    dirs = _directions(nch)
    acc_a, acc_b = np.zeros(ncls), np.zeros(ncls)
    if prior.spread_scale is None:
        lam = None
    elif lam is None:  # a new chain: the classes' scales start at the prior guess
        lam = np.full(ncls, prior.spread**2)
    k_psi = max(nu0 - d - 1.0, 1.0)
    psi_c = np.ascontiguousarray(np.broadcast_to(psi0, (ncls, d, d)))
    if lam is not None:
        psi_c = lam[:, None, None] * (k_psi * np.eye(d))[None]
        lam_shape = 0.5 + 0.5 * d * nu0
        lam_rate0 = 0.5 / prior.spread_scale**2

    def sweep(st: _Sweep, gen: np.random.Generator, it: int) -> _Sweep:
        # One Gibbs sweep (the module notes' steps 1-4); theta, s, t change in place.
        mu, sigma, sig_inv = st.mu, st.sigma, st.sig_inv
        _factor(data.cls, data.g3, data.xy, s, t, sig_inv, chol, u, ok)
        _mu_terms(data.cls, chol, u, ok, sig_inv, prec_data, lin_data)
        mu = _draw_mu(gen, s0_inv, s0_inv_m0, prec_data, lin_data)
        z = gen.standard_normal((nb, d))
        zs = gen.standard_normal((nb, nch))
        g = gen.standard_gamma(gshape)
        sig_inv_mu = np.einsum("cij,cj->ci", sig_inv, mu)
        _bus_sweep(data.cls, chol, u, ok, sig_inv_mu, data.g3, data.xy, data.beta_ls,
                   data.ssr_min, data.fixed, rate, theta, s, t, z, zs, g)  # fmt: skip
        sigma, sig_inv = _scale_moves(gen, data, nu0, psi_c, mu, theta, s, t, sigma, sig_inv,
                                      dirs, acc_a, acc_b)  # fmt: skip
        _class_sums(data.cls, theta, mu, nc, sums, scatter)
        sigma, sig_inv = _draw_sigma(gen, nu0 + nc, psi_c + scatter)
        if lam is not None:
            # lam_c | Sigma_c (the hyperprior's scale, conjugate): after Sigma, in place
            lam_rate = lam_rate0 + 0.5 * k_psi * np.einsum("cii->c", sig_inv)
            lam[:] = gen.standard_gamma(lam_shape, ncls) / lam_rate
            psi_c[:] = lam[:, None, None] * (k_psi * np.eye(d))[None]
        return _Sweep(mu, sigma, sig_inv)

    def record(st: _Sweep) -> dict[str, np.ndarray]:
        return {"theta": theta, "tau": t * s**2, "p0": s * data.scale, "mu": st.mu,
                "sigma": st.sigma}  # fmt: skip

    kept = kept_count(0, total, burn, sampler.thin)
    bus = {"theta": d, "tau": nch, "p0": nch}
    sink = _Store(store, kept, nb, bus) if store else None
    fields = {k: Field((nb, n), np.float32, streamed=True) for k, n in bus.items()}
    fields.update(mu=Field((ncls, d)), sigma=Field((ncls, d, d)))
    chain = Chain(sweep, _Sweep(mu, sigma, sig_inv), gen, fields=fields, record=record,
                  burn=burn, thin=sampler.thin, stop=stop, block=STORE_BLOCK,
                  sink=None if sink is None else sink.write)  # fmt: skip
    chain.run(total)
    kept_draws = chain.draws()
    if sink is not None:
        kept_draws.update(sink.close())
    out = FleetChainDraws(*(kept_draws[k] for k in ("theta", "tau", "mu", "sigma", "p0")))
    end = chain.state
    out.state = ChainState(
        gen.bit_generator.state, end.mu, end.sigma, end.sig_inv, theta, s, t, done + total,
        None if lam is None else lam.copy(),
    )  # fmt: skip
    return out


class _Sweep(NamedTuple):
    """The class-level state a sweep hands on (the bus-level arrays change in place)."""

    mu: np.ndarray
    sigma: np.ndarray
    sig_inv: np.ndarray


def _class_series(data: HierData, chains: Sequence[FleetChainDraws]) -> dict[str, np.ndarray]:
    """Class-level draws, each (class, chain, draw): means a1..a6 and spreads sd_a1.."""
    d = len(data.params)
    col = {p: i for i, p in enumerate(data.params)}
    mu = np.stack([c.mu for c in chains])  # (ch, dr, C, d)
    sd = np.sqrt(np.stack([np.diagonal(c.sigma, axis1=2, axis2=3) for c in chains]))
    series = {p: mu[..., col[p]] for p in data.params}
    for p3, (p1, p2) in _third(data.params).items():
        series[p3] = 1.0 - series[p1] - series[p2]
    names = ["a1", "a2", "a3"] + (["a4", "a5", "a6"] if d == 4 else [])
    out = {p: np.moveaxis(series[p], 2, 0) for p in names}
    out.update({f"sd_{p}": np.moveaxis(sd[..., col[p]], 2, 0) for p in data.params})
    return out


def class_convergence(
    data: HierData, chains: Sequence[FleetChainDraws], hdi_prob: float = 0.95
) -> dict[str, dict[str, np.ndarray]]:
    """Summaries (mean, sd, HDI, R-hat, ESS) of the class-level parameters, per class."""
    return {p: summarize(v, hdi_prob=hdi_prob) for p, v in _class_series(data, chains).items()}


def _third(params: Sequence[str]) -> dict[str, tuple[str, str]]:
    """a3 from (a1, a2), a6 from (a4, a5): the shares that sum to one."""
    out = {"a3": (params[0], params[1])}
    if len(params) == 4:
        out["a6"] = (params[2], params[3])
    return out


def _data_distance(e: np.ndarray, ztz: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Length of ``e`` in each bus's own data precision: sum_ch tau_ch e_ch' Z'Z e_ch."""
    e = e.reshape(e.shape[0], -1, 2)
    q = np.einsum("bci,bij,bcj->bc", e, ztz, e)
    return np.sqrt(np.maximum((tau * q).sum(axis=1), 0.0))


def _bus_series(data: HierData, chains: Sequence[FleetChainDraws], b0: int, b1: int):
    """Every bus-level series of buses ``b0:b1``, each C-contiguous (bus, chain, draw).

    The draws are stored (draw, bus, k) per chain; they are transposed here once, into
    float64 (exact from float32), so the summary reads each series contiguously. The
    derived series (a3, a6, dP/dV, dQ/dV) are the same elementwise operations as ever.
    """
    m, nchain = b1 - b0, len(chains)
    kept = chains[0].mu.shape[0]
    raw = {}
    for name in ("theta", "tau", "p0"):
        first = np.asarray(getattr(chains[0], name)[:, b0:b1])
        out = np.empty((first.shape[2], m, nchain, kept))
        for ci, c in enumerate(chains):
            block = first if ci == 0 else np.asarray(getattr(c, name)[:, b0:b1])
            out[:, :, ci, :] = block.transpose(2, 1, 0)
        raw[name] = out
    col = {p: i for i, p in enumerate(data.params)}
    series = {p: raw["theta"][col[p]] for p in data.params}
    for p3, (p1, p2) in _third(data.params).items():
        series[p3] = 1.0 - series[p1] - series[p2]
    for j, t in enumerate(data.taus):
        series[t] = raw["tau"][j]
    for j, (p0n, slope, (c1, c2)) in enumerate(
        zip(data.nominals, ("dp_dv", "dq_dv"), (("a1", "a2"), ("a4", "a5")), strict=False)
    ):
        series[p0n] = raw["p0"][j]
        # dP/dV at V0 of P = P0 (a1 x^2 + a2 x + a3), x = V / V0
        series[slope] = raw["p0"][j] * (2.0 * series[c1] + series[c2]) / data.v0
    return series


def _bus_rows(data, chains, hp, b0, b1, threads):
    """The bus rows of buses ``b0:b1`` (summaries, shrinkage, warnings)."""
    d = len(data.params)
    names = ["a1", "a2", "a3"] + (["a4", "a5", "a6"] if d == 4 else [])
    series = _bus_series(data, chains, b0, b1)
    order = names + list(data.taus) + list(data.nominals)
    order += ["dp_dv", "dq_dv"][: len(data.nominals)]
    summ = {p: summarize(series.pop(p), hdi_prob=hp, threads=threads) for p in order}
    post_mean = np.stack([summ[p]["mean"] for p in data.params], axis=1)  # (m, d)
    mu_mean = np.mean([c.mu.mean(axis=0) for c in chains], axis=0)  # (C, d)
    own = data.theta_ls[b0:b1].reshape(b1 - b0, d)
    tau_mean = np.stack([summ[t]["mean"] for t in data.taus], axis=1)  # (m, nch)
    ratio = _curvature_ratio(data, chains, tau_mean, b0, b1)
    ztz = data.ztz[b0:b1]

    to_own = _data_distance(post_mean - own, ztz, tau_mean)
    to_cls = _data_distance(post_mean - mu_mean[data.cls[b0:b1]], ztz, tau_mean)
    with np.errstate(invalid="ignore", divide="ignore"):
        shrink = np.where(data.identified[b0:b1], to_own / (to_own + to_cls), 1.0)
    return stat_rows(
        "bus",
        data.buses[b0:b1],
        np.asarray(data.class_names, dtype=object)[data.cls[b0:b1]],
        data.n[b0:b1].astype(np.int64),
        summ,
        warnings=_split_words(data, ratio, b0, b1),
        shrinkage={p: shrink for p in names},
        prior_ratio={p: ratio[:, i // 3] for i, p in enumerate(names)},
    )


def _curvature_ratio(data: HierData, chains, tau_mean: np.ndarray, b0: int, b1: int) -> np.ndarray:
    """Per bus of ``b0:b1`` and channel: how much of its shares' split is its class's.

    Along the curvature ``v = (1, -2) / sqrt 5`` of each channel (``a1 - 2 a2 + a3`` in
    the three shares: the direction a narrow voltage band barely sees, :func:`_directions`)
    the bus's own data give the sd ``s_d = sqrt(v' J^-1 v)``, ``J = tau Z'Z`` with the
    constant (P0) projected out, at the posterior mean of ``tau``; its class gives
    ``s_c = sqrt(E v' Sigma_c v)``. The ratio ``s_d / sqrt(s_d^2 + s_c^2)`` is what the
    posterior sd along ``v`` is of the prior's when these two are all there is: near 1 the
    split is the class's, near 0 the bus's. (The bus's posterior sd itself was tried: it
    also carries the class mean's own uncertainty along ``v``, up to 6 times the spread on
    classes of thin buses, and came out 0.64-0.69 on buses whose own sd along ``v`` was
    three spreads and more: neither says what the bus's data know.)
    A bus whose data identify nothing has 1.
    """
    nch = len(data.taus)
    v = _directions(nch)[1::2]  # (nch, d): the curvature rows
    sig = np.concatenate([np.asarray(c.sigma) for c in chains])  # (draws, C, d, d)
    s_c = np.sqrt(np.einsum("kd,ncde,ke->ck", v, sig, v) / sig.shape[0])[data.cls[b0:b1]]
    g3 = data.g3[b0:b1]
    with np.errstate(invalid="ignore", divide="ignore"):
        zz = g3[:, 1:, 1:] - g3[:, 1:, :1] * g3[:, :1, 1:] / g3[:, :1, :1]
        v2 = np.array([1.0, -2.0]) / np.sqrt(5.0)
        det = zz[:, 0, 0] * zz[:, 1, 1] - zz[:, 0, 1] ** 2
        # v' zz^-1 v for a 2 x 2 matrix
        q = v2[0] ** 2 * zz[:, 1, 1] - 2 * v2[0] * v2[1] * zz[:, 0, 1] + v2[1] ** 2 * zz[:, 0, 0]
        q = q / det
        s_d2 = q[:, None] / tau_mean
        ratio = np.sqrt(s_d2 / (s_d2 + s_c**2))
    ok = data.identified[b0:b1, None] & np.isfinite(ratio) & (det > 0)[:, None]
    return np.where(ok, ratio, 1.0)


def _split_words(data: HierData, ratio: np.ndarray, b0: int, b1: int) -> list[str]:
    """Each bus's warnings, with a sentence per channel whose shares' split is its class's."""
    out = []
    for j, b in enumerate(range(b0, b1)):
        words = [data.warnings[b]] if data.warnings[b] else []
        for ch, (p1, p2, p3, slope) in enumerate(
            (("a1", "a2", "a3", "dp_dv"), ("a4", "a5", "a6", "dq_dv"))[: ratio.shape[1]]
        ):
            if ratio[j, ch] > PRIOR_DRIVEN:
                fixed = f"; {slope} (2 {p1} + {p2}) is what they fix" if data.identified[b] else ""
                words.append(
                    f"{p1}, {p2} not determined separately by its own data: their split is "
                    f"its class's (its data narrow the class spread along {p1} - 2 {p2} + {p3} "
                    f"only to {ratio[j, ch]:.2f} of it, above {PRIOR_DRIVEN}){fixed}"
                )
        out.append(" | ".join(words))
    return out


def summarize_chains(
    data: HierData,
    chains: Sequence[FleetChainDraws],
    sampler: SamplerSettings,
    *,
    batch: int = 128,
) -> pd.DataFrame:
    """The fleet table of a pooled fit: class rows, then bus rows with shrinkage.

    Buses are summarised ``batch`` at a time (what the memory holds: 12 series of 8,000
    float64 draws are 768 kB a bus), the batches shared between
    :func:`~loadbayes.core.parallel.num_threads` threads (reading and transposing the
    draws is half the work, so whole batches run in parallel, not only their compiled
    summaries). Each bus's numbers depend on its own draws only: not on the batches or
    the threads.
    """
    from loadbayes.core.parallel import num_threads, run_threads

    nb = data.buses.size
    hp = sampler.hdi_prob
    bounds = [(b0, min(b0 + batch, nb)) for b0 in range(0, nb, batch)]
    threads = max(1, min(num_threads(), len(bounds)))
    frames: list = [None] * len(bounds)
    inner = None if threads == 1 else 1

    def lane(k: int):
        def run() -> None:
            for i in range(k, len(bounds), threads):
                frames[i] = _bus_rows(data, chains, hp, *bounds[i], inner)

        return run

    run_threads([lane(k) for k in range(threads)])
    cls_stats = class_convergence(data, chains, hp)
    ncls = len(data.class_names)
    frames.insert(
        0,
        stat_rows(
            "class",
            [None] * ncls,
            data.class_names,
            np.bincount(data.cls, minlength=ncls),
            cls_stats,
        ),
    )
    return pd.concat(frames, ignore_index=True)
