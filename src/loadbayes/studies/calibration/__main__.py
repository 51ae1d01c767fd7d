"""``python -m loadbayes.studies.calibration``: the full calibration run (``make validate``)."""

from loadbayes.studies.calibration.run import main

if __name__ == "__main__":
    raise SystemExit(main())
