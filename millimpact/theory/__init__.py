"""Closed-form references the simulations are checked against.

Takes numbers (radii, masses, speeds, moduli, a mill's size, speed and fill), gives Hertz impact
values and histories, the plastic-impact theory (Thornton), the Hertz-dashpot law DEM codes share
(:mod:`millimpact.theory.hertz_dashpot`), and the empirical models mill
engineers check a mill's power draw and charge shape against (Morrell, Austin:
:mod:`millimpact.theory.mill_power`). Imports nothing of millimpact: any stage may use it.
"""
