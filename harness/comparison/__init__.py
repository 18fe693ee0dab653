"""Comparing two result sets, or two commits measured together (`collide-bench compare`): its
command, the verdicts and the calibration of a machine's drift, and its page and figure."""
