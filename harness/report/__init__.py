"""The benchmark report, rendered from whatever results exist, without re-running anything
(`collide-bench report`, and after every run): report/report.{md,html} and their figures, one
page a machine. docs/results.md ("Results and the report") says what a page shows; what an
experiment's section holds is decided by what its rows vary (harness.report.sections).
"""
