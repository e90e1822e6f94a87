"""Results: what a run hands back and writes.

:mod:`.recorder` turns each step's state into time-series rows and the impact's scalar results;
:mod:`.timeseries` holds the columns with units (CSV / HDF5); :mod:`.fields` writes XDMF for
ParaView; :mod:`.reference` the versioned reference files; :mod:`.plots` the figures;
:mod:`.output` the :class:`.output.RunOutput` a method returns. Imports reduction and below.
"""
