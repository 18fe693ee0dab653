"""The benchmark report, rendered from whatever results exist, without re-running anything
(`collide-bench report`, and after every run).

It reads results/<experiment>/{results.csv, env.json, machines/, divergence.csv, outputs/*.txt}
and writes report/report.md, report/report.html and their figures (*.png, *.svg, *.gif), one
page a machine: with several machines each has report/machines/<machine_id>/ and the top page
is the latest's. A part appears only when the data it needs exists; what it shows is decided by
what the experiment's rows vary (particles, square size, radius, threads, builds, print-mode
output), its title by the experiment's `title`.
"""
