"""The liner's damage map (foundations.md section 12): takes a liner scene and a mill's ``impacts.csv``; bins the
impacts by place, speed and angle (:mod:`millimpact.damage.bins`), computes each bin with the table
engine on the liner struck at that place (:mod:`millimpact.damage.places`,
:mod:`millimpact.damage.responses`; a placed scene's many bins read from the adaptive table
engine's cases, :mod:`millimpact.damage.adaptive_bins`; a bin whose contact would reach an edge moved inward or refused
first, :mod:`millimpact.damage.edges`) and each place's repeated-impact sequence, and gives energy,
plastic work and dent growth per place and revolution (:mod:`millimpact.damage.accumulate`,
:mod:`millimpact.damage.report`); :mod:`millimpact.damage.command` is ``millimpact damage``. Imports
dem and below.
"""
