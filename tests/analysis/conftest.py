"""The variants' facts these tests read results with: those stored with the fixture results,
as the report reads each experiment's (harness.spec.facts.reading)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from harness.spec import facts

from fixture_results import fixture_facts


@pytest.fixture(autouse=True)
def stored_facts() -> Iterator[facts.Variants]:
    with facts.reading(fixture_facts()) as variants:
        yield variants
