"""ZIP fits: one reader, a table of variants, two entries.

``from loadbayes.fit.zip import fit_zip, fit_zip_file`` (or ``loadbayes.fit_zip``): a
table in memory or a file (read in chunks when it can be), each taking a
:class:`~loadbayes.core.settings.DataSpec` (``spec``) and a
:class:`~loadbayes.core.settings.SamplerSettings` (``sampler``).

- :mod:`.api`: the entries, their option checks and their routes;
- :mod:`.read`: the reader (a table or a whole file into :class:`.read.ZipData`; a file's
  Gram matrix chunk by chunk);
- :mod:`.variants`: the table of variants (Gaussian, Student-t, drifting level, errors
  in variables), one sampler call each, as :data:`loadbayes.fit.core.METHODS` is for
  any model;
- :mod:`.checks`: the option and data checks, the priors from plain options, the
  derived quantities.
"""

from loadbayes.fit.zip.api import fit_zip, fit_zip_file
from loadbayes.fit.zip.checks import (
    Likelihood,
    add_derived,
    check_likelihood,
    check_v_noise,
    data_checks,
    zip_priors,
)
from loadbayes.fit.zip.variants import VARIANTS

__all__ = [
    "VARIANTS",
    "Likelihood",
    "add_derived",
    "check_likelihood",
    "check_v_noise",
    "data_checks",
    "fit_zip",
    "fit_zip_file",
    "zip_priors",
]
