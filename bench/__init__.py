"""The issues' performance benchmarks (make bench)."""
