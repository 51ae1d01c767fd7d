"""The paper's induction-motor study: Table I, Table III, Fig. 6 and the physical parameters.

For each documented motor (:data:`loadbayes.models.motor_library.MOTORS`) one record is
simulated (default: a 25% sag at 0.5 s for 150 ms, 3 s at 1 ms = 3001 samples, noise sd
5% of each target channel's RMS, on the targets only as in the paper) and fitted five
ways on the same data:

=================  ==========================================================
``gs``             Gibbs, modelled currents (the coupled blocks; the default)
``ls``             least squares of the same coupled model (maximum likelihood)
``gs_measured``    Gibbs, the paper's form (measured currents as regressors)
``ls_measured``    least squares of the paper's three blocks
``kf_measured``    Kalman filter on the paper's blocks (no process noise)
=================  ==========================================================

plus an errors-in-variables table on one motor (noise on the targets only, or on the
regressors too, for both forms). :func:`run` computes, :func:`write` writes
``OUT/im/`` and the IM section of ``OUT/report.html``; :func:`html_section` returns the
section for the report assembler.

The package has one module per job: ``study`` (settings and the result types),
``compute`` (:func:`run`), ``tables``, ``charts`` (matplotlib figures), ``text`` (the
sentences on each difference from the paper), ``html`` (:func:`html_section`) and
``files`` (:func:`write`, :func:`output_paths`).
"""

from loadbayes.studies.im_paper.charts import figures
from loadbayes.studies.im_paper.compute import run
from loadbayes.studies.im_paper.files import output_paths, update_report, write
from loadbayes.studies.im_paper.html import html_section
from loadbayes.studies.im_paper.study import (
    EIV_MOTOR,
    FULL,
    METHODS,
    PAPER_TABLE1,
    PAPER_TABLE3,
    PHYSICAL,
    QUICK,
    ImStudy,
    MotorRun,
)
from loadbayes.studies.im_paper.tables import physical_table, table1, table3, text_tables

__all__ = [
    "EIV_MOTOR",
    "FULL",
    "ImStudy",
    "METHODS",
    "MotorRun",
    "PAPER_TABLE1",
    "PAPER_TABLE3",
    "PHYSICAL",
    "QUICK",
    "figures",
    "html_section",
    "output_paths",
    "physical_table",
    "run",
    "table1",
    "table3",
    "text_tables",
    "update_report",
    "write",
]
