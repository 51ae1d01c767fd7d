"""The paper's ZIP study on the IEEE 33-bus feeder, reproduced with its baselines.

What it does (the paper's section "Case Study: ZIP Model Identification" and
"Benchmarks"; docs/paper.md for what the paper leaves unsaid):

1. Data: ``N = max(n, largest sweep n)`` power flows of ``case33bw`` with the ZIP load
   (0.25, 0.25, 0.5) at bus 18 and every other load scaled by its own U[0.1, 4.5]
   factor (:func:`loadbayes.cases.ieee33.generate_experiments`), noise sd ``noise`` in
   per unit of P0 and Q0 on P and Q. The fit uses the first ``n`` experiments; the sweep
   uses nested prefixes of the same ``N``, so nothing is generated twice.
2. Fits on the same data: Gibbs with blocked (a1, a2) (``GS``, the project's default),
   Gibbs one coefficient at a time (the paper's Algorithm 1), least squares with the
   sum-to-one constraint (``LS``) and without it (three free coefficients), a Kalman
   filter on (a1, a2) (``KF``: no process noise by default) and one with a random walk.
3. Validation: 100 fresh experiments (their own seed); power flow with the true ZIP and
   with each estimate (P and Q shares); ``dX = X_est - X_true`` at bus 18. Posterior-
   predictive power flows over a few hundred posterior draws give a 95% band of V and P.
4. Table II: mean absolute relative error, in %, of V and of P at bus 18 over the
   validation experiments::

       voltage_error_pct = 100 * mean_i |V_est,i - V_true,i| / V_true,i
       power_error_pct   = 100 * mean_i |P_est,i - P_true,i| / P_true,i

   where ``X_true`` is the power flow with the true ZIP load and ``X_est`` the one with
   the estimated ZIP load, on the same experiment (load factors). The paper calls it "the
   average absolute mean of voltage and active power errors" and gives no formula.
5. Sweep: posterior sd of a1 and a2 against n and noise (blocked Gibbs with the study's
   priors, and the least-squares standard error from the same sufficient statistics).

:func:`run` computes, :func:`write` writes ``OUT/zip/`` and the ZIP section of
``OUT/report.html`` (between ``<!-- loadbayes:section zip -->`` markers, as the motor
study does), :func:`html_section` returns that section.

The package has one module per job: ``study`` (settings and the result type),
``compute`` (:func:`run`), ``validation`` (the validation power flows), ``tables``,
``charts`` (matplotlib figures), ``text`` (the sentences on each difference from the
paper), ``html`` (:func:`html_section`) and ``files`` (:func:`write`,
:func:`output_paths`).
"""

from loadbayes.studies.zip_paper.charts import figures

# _columns and _validation_seed: re-exported for the tests that check them.
from loadbayes.studies.zip_paper.compute import _columns as _columns
from loadbayes.studies.zip_paper.compute import _validation_seed as _validation_seed
from loadbayes.studies.zip_paper.compute import run
from loadbayes.studies.zip_paper.files import marked, output_paths, update_report, write
from loadbayes.studies.zip_paper.html import html_section
from loadbayes.studies.zip_paper.study import (
    FULL,
    KF_RANDOM_WALK,
    METHODS,
    PAPER_MEANS,
    PAPER_TABLE2,
    PAPER_VALIDATION,
    QUICK,
    SD_TARGETS,
    SWEEP_NOISE,
    TABLE2_ROWS,
    TRUE_ZIP,
    ZipStudy,
)
from loadbayes.studies.zip_paper.tables import (
    comparison,
    error_pct,
    needed_n,
    predictive_summary,
    required_n,
    sampler_table,
    study_table2,
    table2,
    text_tables,
    validation_summary,
)

__all__ = [
    "FULL",
    "KF_RANDOM_WALK",
    "METHODS",
    "PAPER_MEANS",
    "PAPER_TABLE2",
    "PAPER_VALIDATION",
    "QUICK",
    "SD_TARGETS",
    "SWEEP_NOISE",
    "TABLE2_ROWS",
    "TRUE_ZIP",
    "ZipStudy",
    "comparison",
    "error_pct",
    "figures",
    "html_section",
    "marked",
    "needed_n",
    "output_paths",
    "predictive_summary",
    "required_n",
    "run",
    "sampler_table",
    "study_table2",
    "table2",
    "text_tables",
    "update_report",
    "validation_summary",
    "write",
]
