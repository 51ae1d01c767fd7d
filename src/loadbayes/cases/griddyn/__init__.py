"""GridDyn (LLNL) as an independent simulator of the WECC composite load (CMLDBLU1).

``cases.run_case`` runs one fault case in GridDyn's own environment (Python >= 3.13,
``make griddyn-env``) and returns the measured bus's record and its truth; ``cmld.py``
describes the load; ``events.griddyn_events`` adds noise. The tests and the demo's
planning section use it; nothing here imports the rest of loadbayes.
"""
