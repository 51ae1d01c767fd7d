"""IEEE 33-bus feeder with a ZIP load at bus 18: the paper's power-flow data generator.

The paper (section "Case Study: ZIP") takes the Baran & Wu 33-bus feeder, replaces the
load at bus 18 with a ZIP load, multiplies every other load by its own factor drawn
from U[0.1, 4.5] in each experiment, runs a power flow and records V, P and Q at bus 18.
Here the feeder is pandapower's ``case33bw``; the paper's bus 18 is pandapower bus 17
(the paper numbers buses from 1, pandapower from 0).

ZIP load in pandapower
----------------------
pandapower models the load of bus ``k`` with nominal ``P0 = p_mw * scaling`` as::

    P = P0 (cz V^2 + ci V + (1 - cz - ci)),   cz = const_z_p_percent / 100,
                                              ci = const_i_p_percent / 100

with ``V = vm_pu`` relative to the bus's ``vn_kv`` (so V0 = 1.0 p.u.), and the same for
Q with ``const_z_q_percent`` and ``const_i_q_percent``. So the paper's ``a1 = cz``,
``a2 = ci``, ``a3 = 1 - a1 - a2`` (``a4``, ``a5``, ``a6`` for Q), and
``y = P / P0`` in this module is ``res_load.p_mw / p_mw``. Checked in pandapower 3.5:
``res_load`` and ``res_bus`` follow the formula to machine precision, and the network
injection ``V conj(Ybus V)`` at bus 17 matches it to the power-flow tolerance.

Coefficient limits found in pandapower 3.5: a negative ``a1`` or ``a2`` (a percent below
0 or above 100) is accepted and solved correctly; ``a1 + a2 > 1`` (a negative constant-
power share ``a3``) is refused with a ``ValueError`` when the case is built. The
``"newton"`` engine writes the shares into the solver's bus matrix directly, so it takes
any real coefficients that sum to one; ``"runpp"`` and ``"recycle"`` cannot take a3 < 0.
pandapower also *averages* the percentages of all loads at a bus without weighting them
by their power, and ``res_load`` then disagrees with the power flow; that is why
exactly one load sits at bus 17 here.

Engines (``Feeder33(engine=...)``)
-----------------------------------
``"newton"`` (default)
    pandapower's own Newton-Raphson (``pandapower.pypower.newtonpf``, the function
    ``runpp`` calls) on the admittance matrix and bus table that a first ``runpp`` built;
    each run only rewrites the bus loads and the ZIP shares and starts flat. It skips
    pandapower's pandas bookkeeping (for a ZIP load that is a Python loop over buses),
    which is most of ``runpp``'s time. It uses pandapower internals, so the feeder checks
    itself against ``runpp`` when it is built.
``"recycle"``
    ``runpp(net, recycle={"bus_pq": True, "trafo": False, "gen": False})``, pandapower's
    time-series fast path. ``bus_pq`` must be True (else the new loads are silently
    ignored); ``trafo`` and ``gen`` may be False because branches and the slack do not
    change. It warm-starts from the previous solution, so results depend on the order of
    runs at the tolerance level, and after a failed run the stale voltages make the next
    feasible runs fail too; the engine therefore does a full ``runpp`` after a failure,
    at the start of every chunk, and when the ZIP shares change (pandapower turns its
    voltage-dependent-load option off when the first full run has no ZIP share).
``"runpp"``
    a plain ``runpp`` per experiment: the reference.

Every engine uses the same tolerance (``tolerance_mva``, default 1e-10; pandapower's
default is 1e-8, compared with the mismatch in per unit of ``net.sn_mva`` = 10 MVA).
Two runs from different starting points then agree to about 1e-10 in V; at 1e-8 they can
differ by 2e-8 at bus 18, because pandapower's Jacobian omits the ZIP load's voltage
derivative and the last Newton step is not quadratically small.

Modules
-------
``network`` (constants, pandapower access, the base case), ``engines`` (the three
power-flow engines; the one that uses pandapower internals is ``NewtonEngine``),
``feeder`` (:class:`Feeder33`), ``parallel`` (chunks and the process pool) and ``draws``
(:func:`draw_factors`, :func:`generate_experiments`). The validation study that used to
live here is :func:`loadbayes.studies.ieee33_validation.validate`.
"""

from loadbayes.cases.ieee33.draws import FACTOR_RANGE, draw_factors, generate_experiments
from loadbayes.cases.ieee33.feeder import Feeder33
from loadbayes.cases.ieee33.network import (
    DEFAULT_ZIP,
    ENGINES,
    N_FACTORS,
    ZIP_BUS,
    BusSolution,
    base_case,
)

__all__ = [
    "DEFAULT_ZIP",
    "ENGINES",
    "FACTOR_RANGE",
    "N_FACTORS",
    "ZIP_BUS",
    "BusSolution",
    "Feeder33",
    "base_case",
    "draw_factors",
    "generate_experiments",
]
