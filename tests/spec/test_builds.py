"""The builds the harness knows are the ones the Makefile makes, each with its arithmetic."""

from __future__ import annotations

import subprocess

from harness import repo
from harness.spec import builds


def test_the_harness_knows_every_build_the_makefile_makes() -> None:
    made = subprocess.run(["make", "-s", "print-builds"], cwd=repo.REPO_ROOT, check=True,
                          capture_output=True, text=True).stdout.split()
    assert [builds.DEFAULT_BUILD, *made] == list(builds.BUILDS)
    assert set(builds.UNIT_ROUNDOFF) == set(builds.BUILDS) == set(builds.DESCRIPTIONS)


def test_binary_names() -> None:
    assert builds.binary_name("seq", builds.DEFAULT_BUILD) == "seq"
    assert builds.binary_name("grid", "f128") == "grid-f128"
    assert builds.unit_roundoff("f32") == 2.0**-24
    assert builds.unit_roundoff("a-custom-build") == builds.DOUBLE_EPS
