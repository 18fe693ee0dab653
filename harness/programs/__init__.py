"""Programs, implementations of the model written elsewhere (`programs:` in a config, parsed by
harness.spec.programs): a program's cell run and its printed states judged against seq step by
step (cell; agreement, printed, steps, events; races: ThreadSanitizer on a copy built from its
source), the tables a class is graded by (tables) and the report's section and figure
(section, figure). The core imports none of it: the command line lends it what measures a
program's cell and its part of the report (hooks)."""
