"""The DEM round trip (DESIGN.md 11). :mod:`.export` (``millimpact export``) takes a contact table's
folder and gives the contact law for Yade, LIGGGHTS and LAMMPS (:mod:`.contact_law`,
:mod:`.export_files`), checked in Yade with ``--check`` (:mod:`.roundtrip`); :mod:`.mill`
(``millimpact mill``) takes a liner scene and gives a mill slice's impact log, ``impacts.csv``
(:mod:`.impacts`, the contract the damage map reads). Yade runs as a subprocess (:mod:`.yade`,
scripts in ``yade_scripts/``). Imports studies and below.
"""
