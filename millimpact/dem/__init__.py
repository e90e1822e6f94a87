"""The DEM round trip: contact laws exported for DEM codes (Yade, LIGGGHTS, LAMMPS), checked by
running Yade, and a mill slice run in Yade that logs its ball-liner impact spectrum (DESIGN.md 11)."""
