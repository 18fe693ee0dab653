"""The variants' facts these tests read results with: those stored with the fixture results,
passed explicitly wherever results are ordered, coloured or judged by them, as the report
passes each experiment's."""

from __future__ import annotations

import pytest
from harness.spec.facts import Variants

from fixture_results import fixture_facts


@pytest.fixture
def facts() -> Variants:
    return fixture_facts()
