"""Planning: a config's cells (cells), the binaries they run and their identity and storage
(cellstore: binaries, keys, ids, records, inputs), and the instruction lane (lane)."""
