"""Running experiments: one config at a time (experiment.run_experiment), planned, built,
resumed from cached records, measured by an executor, summarised."""
