"""Reports of any fit: a self-contained HTML page, the terminal table, the notebook view.

``text.py`` formats numbers and tables, ``figures.py`` draws a fit's figures as inline
images, ``page.py`` assembles the page (summary first, contents, captioned figures) and
``fit_report.py`` builds the report of one fit; ``fleet_table.py`` reads and checks a
fleet's Parquet table, ``fleet_figures.py`` and ``fleet_report.py`` make its page.
The composite's: ``composite_names.py`` (its vocabulary: every named draw's unit and
meaning), ``composite_table.py`` (the table ``fit composite`` prints) and
``composite.py`` (its sections of the report).
Nothing here imports :mod:`loadbayes.studies`; the paper's report is built on these
pieces.
"""
