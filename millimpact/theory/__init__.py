"""Closed-form contact mechanics: the independent references the simulations are checked against.

Takes numbers (radii, masses, speeds, moduli), gives Hertz impact values and histories (and the
plastic-impact theory as it lands). Imports nothing of millimpact: any stage may use it.
"""
