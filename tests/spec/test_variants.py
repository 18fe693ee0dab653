"""The variant registry: what each variant is comes from its binary's `--describe`, the order
tables show variants in follows from those facts, and a bad description is one clear error."""

from __future__ import annotations

import json
import stat
from pathlib import Path

import pytest
from harness.errors import HarnessError
from harness.spec import variants
from harness.spec.variants import BASELINE, VariantFacts, VariantRegistry, default_registry


def facts(name: str, *, all_pairs: bool = True, repairs: str | None = None,
          exact: bool = True, parallel: bool = True) -> VariantFacts:
    return VariantFacts(name, f"{name}'s way", exact, parallel, all_pairs, repairs)


def test_the_binaries_describe_the_spec_variants() -> None:
    """SPEC section 6, read back from the binaries: seq is the serial baseline, relative the one
    variant that is not exact, and the seed's strategies repaired where a repair exists."""
    registry = default_registry()
    assert {"seq", "p1", "p2", "p3", "p1d", "p2d", "relative", "grid"} <= set(registry.names)
    assert registry["seq"].parallel is False and registry["seq"].all_pairs
    assert [n for n in registry.names if not registry[n].exact] == ["relative"]
    assert not registry["grid"].all_pairs and not registry["relative"].all_pairs
    assert registry.repaired_by("p1") == ("p1_cyclic",)
    assert all(registry[n].summary for n in registry.names)


def test_order_puts_the_baseline_first_and_repairs_after_what_they_repair() -> None:
    table = {f.name: f for f in (
        facts("zz_broad", all_pairs=False), facts("b"), facts("a_fix", repairs="b"),
        facts("a"), facts(BASELINE, parallel=False), facts("odd", repairs="gone"),
        facts("fast", all_pairs=False, exact=False))}
    assert variants.ordered(table) == (BASELINE, "a", "b", "a_fix", "odd", "fast", "zz_broad")
    registry = VariantRegistry.of(table.values())
    assert registry.families == (BASELINE, "a", "b", "odd", "fast", "zz_broad")
    assert registry.family("a_fix") == "b" and registry.rank("nobody") == len(table)


def test_the_default_registry_can_be_replaced_for_a_while() -> None:
    mine = VariantRegistry.of([facts(BASELINE, parallel=False), facts("only")])
    with variants.using(mine):
        assert default_registry() is mine and default_registry().order == (BASELINE, "only")
    assert default_registry() is not mine


def write_binary(path: Path, stdout: str, status: int = 0) -> Path:
    path.write_text(f"#!/bin/sh\ncat <<'EOF'\n{stdout}\nEOF\nexit {status}\n")
    path.chmod(path.stat().st_mode | stat.S_IXUSR)
    return path


@pytest.mark.parametrize(("stdout", "status", "message"), [
    ("not json", 0, "printed no JSON object"),
    (json.dumps({"name": "v"}), 0, "lacks 'summary'"),
    (json.dumps({**facts("v").__dict__, "exact": "yes"}), 0, "'exact' is 'yes'"),
    (json.dumps(facts("other").__dict__), 0, "names the variant 'other'"),
    ("", 2, r"--describe failed \(exit 2\)"),
])
def test_a_bad_description_is_one_error_naming_the_binary(tmp_path: Path, stdout: str,
                                                          status: int, message: str) -> None:
    binary = write_binary(tmp_path / "v", stdout, status)
    with pytest.raises(HarnessError, match=message) as info:
        variants.describe(binary)
    assert str(binary) in str(info.value)


def test_a_good_description_parses(tmp_path: Path) -> None:
    binary = write_binary(tmp_path / "v", json.dumps(facts("v", repairs="p1").__dict__))
    assert variants.describe(binary) == facts("v", repairs="p1")


def test_an_unknown_variant_is_named_with_the_known_ones() -> None:
    registry = VariantRegistry.of([facts(BASELINE), facts("p1")])
    with pytest.raises(HarnessError, match="unknown variant 'p9'; expected one of: seq, p1"):
        registry["p9"]
