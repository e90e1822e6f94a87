"""``millimpact export``: a contact table's law for a DEM code (:mod:`.command`). The table is read by
:mod:`.table_input`, the Hertz-dashpot law fitted per point by :mod:`millimpact.theory.hertz_dashpot`, the files for
Yade, LIGGGHTS and LAMMPS written by :mod:`.files`, and ``--check`` runs them in Yade
(:mod:`.roundtrip`, scripts in ``yade_scripts/``).
"""
