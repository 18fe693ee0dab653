"""The performance benchmarks (make bench)."""
