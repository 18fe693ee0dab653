"""What results mean, read back from results.csv: the typed frame (frame), which columns name a
cell (cells), speedups (speedup), flags and warnings (flags), error against time (accuracy),
the checks (trust), where the time goes (phases), the strategy study (strategies), compare's
verdicts (compare), and how each reads as text (display). Pure functions of DataFrames; nothing
here measures or draws."""
