"""The DEM round trip (design.md section 11). :mod:`millimpact.dem.export` (``millimpact export``) takes a
contact table's folder and gives the contact law for Yade, LIGGGHTS and LAMMPS
(:mod:`millimpact.dem.contact_law`, :mod:`millimpact.dem.export_files`), checked in Yade with
``--check`` (:mod:`millimpact.dem.roundtrip`); :mod:`millimpact.dem.mill` (``millimpact mill``)
takes a liner scene and gives a mill slice's impact log, ``impacts.csv``
(:mod:`millimpact.dem.impacts`, the contract the damage map reads). Yade runs as a subprocess
(:mod:`millimpact.dem.yade`, scripts in ``yade_scripts/``). Imports studies and below.
"""
