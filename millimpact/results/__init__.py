"""Results: what a run hands back and writes.

:mod:`.recorder` turns each step's state into time-series rows and the impact's scalar results;
:mod:`.reduced_recorder` gives the same rows from a reduced model's coordinates (and a closed-form
free phase's, all at once); :mod:`.timeseries` holds the columns with units (CSV / HDF5);
:mod:`.fields` writes XDMF for ParaView; :mod:`.reference` the versioned reference files;
:mod:`.plots` the figures; :mod:`.output` the :class:`.output.RunOutput` a method returns. The
recorders take the model, its contact set and the plan's probe spec, never the scene (the file
writers take its name and TOML text). Imports reduction and below.
"""
