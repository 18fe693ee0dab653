"""What an experiment is, before anything runs: configs (config, kinds, parse, programs),
scenes (scenes and the stiff-scene catalog), the variants and their builds (facts, variants,
builds) and the output format every variant writes (output).

Importing the package registers every scene generator (the catalog's too), so a config can
name any of them.
"""

from harness.spec import catalog as _catalog  # noqa: F401  (registers its generators)
