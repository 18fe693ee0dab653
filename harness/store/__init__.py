"""The store: what measurements leave behind (the results layout, cell records and their keys,
results.csv and the files beside it, superseded records, the locks), and how it is read back.
Nothing here measures, plans or analyses."""
