"""Tolerance sweeps of the drive train: many twin closed-loop runs of BacklashShaft.fmu with the
rig's parameters drawn from distributions, serially or on a Dask cluster (`python -m sweep`)."""
