"""collide-bench experiment harness: configs, scenes, measurement, validation, results.

The core, in layers, each importing only those below it (pyproject.toml's import-linter
contracts keep them so):

    cli          the command line: flags parsed, a layer or a feature called
    report       the report's pages, sections and figures
    runner       an experiment run: plan, build, measure, export; two sides measured together
    executors    where cells are measured: here in alternating rounds, or as Slurm tasks
    measure      one cell's runs, validation, checks, noise
    plan         a config's cells and their identities
    analysis     the read model (analysis.results: the one reader of stored results), the
                 statistics of what is read, and the exports (results.csv, ratios.csv)
    spec, store  configs and scenes; records and the files beside them
    stats        statistics, standard library and scipy

Features stand on the core and not on each other, each one package with its command, its
analysis and its report part: comparison, history, reruns and programs. The core imports no
feature: where it calls one, the feature lends a hook that the command line passes in
(docs/extending.md).
"""
