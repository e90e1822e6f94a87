"""The DEM round trip: two commands in two subpackages of the same shape as
:mod:`millimpact.repeat` and :mod:`millimpact.damage` (``command.py`` plus its modules):
:mod:`millimpact.dem.export` (``millimpact export``) takes a contact table's folder and gives the
contact law for Yade, LIGGGHTS and LAMMPS, checked in the code itself with ``--check``;
:mod:`millimpact.dem.mill` (``millimpact mill``) takes a liner scene and gives a mill slice's
impact log, ``impacts.csv``. What both use sits here: :mod:`millimpact.dem.impacts` (impacts.csv,
the contract the damage map reads), :mod:`millimpact.dem.yade` (Yade run as a subprocess; each
subpackage keeps its scripts in its own ``yade_scripts/``) and :mod:`millimpact.dem.programs`
(any DEM code found and run as a subprocess). Imports studies and below.
"""
