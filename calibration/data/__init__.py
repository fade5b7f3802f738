"""Measured data: the Dataset and the measurement CSV (docs/formats.md §1).

Modules
-------
dataset             Dataset and the measurement CSV, CsvTable for every table
columns             the column table: every per-point quantity once (CSV, store, Dataset)
capture_meta        CaptureMeta: the capture context a measurement file carries
orientation_columns the CSV's orientation columns (qw, qx, qy, qz, sigma_deg)
"""
