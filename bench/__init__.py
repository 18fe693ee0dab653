"""Analysis tools beside the benchmarks (the benchmarks themselves are configs/bench-*.yaml,
measured by the harness's run: `make bench`)."""
