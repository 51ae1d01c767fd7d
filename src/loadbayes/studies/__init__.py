"""The paper's studies and the ones past it: they use the library; the library never uses them.

``zip_paper`` (the 33-bus ZIP study), ``im_paper`` (the motor study), ``robust``,
``tracking`` and ``model_choice`` (past the paper), ``calibration`` (SBC, coverage and
Geweke runs behind ``make validate``) and ``report`` (the self-contained HTML page).
Each study is a function that returns tables and figures; ``loadbayes reproduce`` calls
them.
"""
