"""Measuring one cell: its runs (proc), validation against seq (references), the accuracy and
stability checks (checks, invariants, shadow), its rounds of hyperfine (rounds), what
--timing and build/ompcost report (timing), and where it ran (machine, environment).
cell.Measurer puts them together; a program's cell it measures by the hook the programs
feature lends (harness.programs)."""
