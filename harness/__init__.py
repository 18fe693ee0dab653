"""collide-bench experiment harness: configs, scenes, measurement, validation, results."""
