"""Planning: a config's cells (cells), the binaries they run (binaries), and their identity and
storage (cellstore: keys, ids, records, inputs). Nothing here measures."""
