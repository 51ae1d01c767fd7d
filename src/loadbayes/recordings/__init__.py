"""Recordings in: COMTRADE waveforms, PMU phasor CSVs, and the events found in them.

- :mod:`~loadbayes.recordings.comtrade`: read a COMTRADE ``.cfg``/``.dat`` pair (IEEE
  C37.111 1991, 1999, 2013; ASCII, BINARY, BINARY32, FLOAT32), validated line by line;
- :mod:`~loadbayes.recordings.phasors`: per-cycle positive-sequence V, total P, Q and
  frequency from three-phase waveforms (one-cycle DFT);
- :mod:`~loadbayes.recordings.phasor_fit`, :mod:`~loadbayes.recordings.record`: sliding
  least-squares phasors and a record's table (sequences, positive-sequence P, Q, the
  magnitudes of amplitude segments); :mod:`~loadbayes.recordings.record_file`: that table
  on disk with its metadata sidecar, and its events; :mod:`~loadbayes.recordings.plausible`:
  physics checks of the table;
- :mod:`~loadbayes.recordings.pmu`: PMU historian CSVs (C37.118 quantities);
- :mod:`~loadbayes.recordings.events`: voltage sags found in a long record, one file each;
- :mod:`~loadbayes.recordings.synth`: synthetic COMTRADE files with a known load behind
  them (for tests, docs and users checking their own chain).

Every reader returns plain per-unit columns ``t_s, v, p, q[, f]``, the form that
``loadbayes fit zip`` and ``loadbayes fit composite`` read.
"""
