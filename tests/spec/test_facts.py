"""The variants' facts as results store them: written and read back unchanged, ordered as the
registry orders them, and a malformed file is one error naming the file and what is wrong."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from harness.errors import HarnessError
from harness.spec import facts
from harness.spec.facts import Count, SyncFacts, VariantFacts, Variants, read_variants

from fixture_results import fixture_facts

SEED = VariantFacts("p2", "the seed's", exact=True, parallel=True, all_pairs=True,
                    sync=SyncFacts(regions=Count(row=1), grabs=Count(pair=1, step=2)))
REPAIR = VariantFacts("p2_blocks", "p2 repaired", exact=True, parallel=True, all_pairs=True,
                      repairs="p2")
BASE = VariantFacts("seq", "the baseline", exact=True, parallel=False, all_pairs=True)
OTHER = VariantFacts("grid", "cells", exact=True, parallel=True, all_pairs=False)


def test_stored_facts_read_back_unchanged(tmp_path: Path) -> None:
    variants = Variants.of([OTHER, REPAIR, SEED, BASE])
    path = tmp_path / "variants.json"
    path.write_text(json.dumps(variants.to_json()))
    assert read_variants(path) == variants
    assert read_variants(path).digest() == variants.digest()
    # the sync counts are written as --describe prints them: only the terms that are not zero
    stored = json.loads(path.read_text())["variants"]
    assert stored[1]["sync"]["grabs"] == {"step": 2, "pair": 1}


def test_the_order_is_baseline_all_pairs_families_then_the_rest() -> None:
    variants = Variants.of([OTHER, REPAIR, SEED, BASE])
    assert variants.order == ("seq", "p2", "p2_blocks", "grid")
    assert variants.families == ("seq", "p2", "grid")
    assert variants.repaired_by("p2") == ("p2_blocks",)
    assert variants.family("custom") == "custom"


def test_the_fixture_results_carry_the_facts_of_every_variant() -> None:
    stored = fixture_facts()
    assert stored.order[0] == facts.BASELINE and "p1d" in stored
    assert stored["p1_cyclic"].repairs == "p1"


def test_absent_facts_are_none(tmp_path: Path) -> None:
    assert read_variants(tmp_path / "variants.json") == Variants() == facts.NO_FACTS
    assert Variants().order == () and Variants().get("seq") is None


@pytest.mark.parametrize(("content", "message"), [
    ("{", "not JSON"),
    ('{"variants": {}}', "expected an object with a list 'variants'"),
    ('{"variants": [{"name": "seq"}]}', "variants[0]: --describe lacks 'summary'"),
    ('{"variants": [' + json.dumps(BASE.to_json()) + "," + json.dumps(BASE.to_json()) + "]}",
     "variant(s) listed twice: seq"),
])
def test_a_malformed_file_is_one_error_naming_it(tmp_path: Path, content: str,
                                                 message: str) -> None:
    path = tmp_path / "variants.json"
    path.write_text(content)
    with pytest.raises(HarnessError, match=r"variants\.json") as caught:
        read_variants(path)
    assert message in str(caught.value) and "\n" not in str(caught.value)
