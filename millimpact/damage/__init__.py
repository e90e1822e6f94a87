"""The liner's damage map (DESIGN.md 12): takes a liner scene and a mill's ``impacts.csv``; bins
the impacts by place, speed and angle (:mod:`.bins`), computes each bin with the table engine on
the liner struck at that place (:mod:`.places`, :mod:`.responses`) and each place's repeated-impact
sequence, and gives energy, plastic work and dent growth per place and revolution
(:mod:`.accumulate`, :mod:`.report`); :mod:`.command` is ``millimpact damage``. Imports dem and below.
"""
