"""Measuring one cell: its runs (proc), validation against seq (validate, references, agreement,
printed: an output read back), the accuracy and stability checks (checks, invariants, shadow),
hyperfine (hyperfine), what --timing reports (timing), and where it ran (machine, environment).
cell.Measurer puts them together."""
