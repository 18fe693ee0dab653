"""The benchmark report, rendered from whatever results exist, without re-running anything
(`collide-bench report`, and after every run).

It reads results/<experiment>/{results.csv, env.json, divergence.csv, outputs/*.txt} and writes
report/report.md, a self-contained report/report.html and report/figures/*.{png,svg,gif}. A
part appears only when the data it needs exists; what it shows is decided by what the
experiment's rows vary (particles, square size, radius, threads, builds, machines, print-mode
output), its title by the experiment's `title`.

Modules: document (the model), blocks (tables and figures as blocks), sections (one module a
part of an experiment's section, registered in sections.PARTS), figures (one module a kind of
figure), summary, header and parts (what spans experiments), markdown and html (writing it),
cache (render only what changed), discover and load (what to read), pipeline (render under a
lock), compare (compare's output).
"""
