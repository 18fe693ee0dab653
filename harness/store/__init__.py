"""The store: what measurements leave behind, and how it is read back.

layout (where each file lives), atomic (write and rename), locks (the machine-wide measuring
lock, a results directory's lock), columns (results.csv's contract and the statuses), records
(cell records and their ids), hyperfine (its exports), csvfile (results.csv and divergence.csv
from records), history (current and superseded records), index (results.csv rebuilt from the
records on disk). Nothing here measures, plans or analyses.
"""
