"""What stored results mean: tables as DataFrames and sentences as strings, computed from
results rows, for the report and the commands to lay out. Nothing here measures or draws."""
