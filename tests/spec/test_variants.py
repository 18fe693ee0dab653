"""The variant registry: what each variant is comes from its binary's `--describe`, the order
tables show variants in follows from those facts, and a bad description is one clear error."""

from __future__ import annotations

import json
import re
import stat
import subprocess
from pathlib import Path

import pytest
from harness.errors import HarnessError
from harness.spec import variants
from harness.spec.facts import BASELINE, Count, SyncFacts, VariantFacts, Variants
from harness.spec.variants import VariantRegistry, default_registry

from conftest import build_or_skip


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
    assert registry.known.repaired_by("p1") == ("p1_cyclic",)
    assert all(registry[n].summary for n in registry.names)


def test_order_puts_the_baseline_first_and_repairs_after_what_they_repair() -> None:
    table = {f.name: f for f in (
        facts("zz_broad", all_pairs=False), facts("b"), facts("a_fix", repairs="b"),
        facts("a"), facts(BASELINE, parallel=False), facts("odd", repairs="gone"),
        facts("fast", all_pairs=False, exact=False))}
    assert Variants.of(table.values()).order == (BASELINE, "a", "b", "a_fix", "odd", "fast",
                                                 "zz_broad")
    registry = VariantRegistry(facts=table.values())
    assert registry.known.families == (BASELINE, "a", "b", "odd", "fast", "zz_broad")
    assert registry.known.family("a_fix") == "b"


def test_the_default_registry_can_be_replaced_for_a_while() -> None:
    mine = VariantRegistry(facts=[facts(BASELINE, parallel=False), facts("only")])
    with variants.using(mine):
        assert default_registry() is mine and default_registry().known.order == (BASELINE, "only")
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
    registry = VariantRegistry(facts=[facts(BASELINE), facts("p1")])
    with pytest.raises(HarnessError, match="unknown variant 'p9'; expected one of: seq, p1"):
        registry["p9"]


# --- the finders' OpenMP operations per step (`sync`) -------------------------------------


def test_the_seed_strategies_declare_their_operations_per_step() -> None:
    """p1 and p1d fork one team a step, p2 one a row, p3 a team per row inside its outer team,
    p2d one a row and a grab per pair test; their repairs one team a step."""
    registry = default_registry()
    n = 1000
    per_step = {name: registry[name].sync.per_step(n)  # type: ignore[union-attr]
                for name in ("p1", "p1_cyclic", "p1d", "p2", "p2_blocks", "p3", "p2d",
                             "p2d_tiles", "seq")}
    assert per_step["p1"] == {"regions": 1, "nested_regions": 0, "barriers": 0, "grabs": 0}
    assert per_step["p1_cyclic"] == per_step["p2_blocks"] == per_step["p1"]
    assert per_step["p1d"] == {**per_step["p1"], "grabs": n}
    assert per_step["p2"] == {**per_step["p1"], "regions": n}
    assert per_step["p3"] == {**per_step["p1"], "nested_regions": n}
    assert per_step["p2d"] == {**per_step["p2"], "grabs": n * (n - 1) / 2}
    assert per_step["p2d_tiles"]["regions"] == 1 and per_step["seq"]["regions"] == 0
    # where the count depends on the data or on OMP_SCHEDULE, none is declared
    assert registry["grid"].sync is None and registry["p1_runtime"].sync is None


@pytest.mark.parametrize("n", [1, 2, 7, 4096, 4097, 10000])
def test_tiles_per_step_are_every_rows_tiles(n: int) -> None:
    tile = 4096
    count = Count(tile=1)
    assert count.per_step(n, tile) == sum(-(-(n - 1 - i) // tile) for i in range(n))


@pytest.mark.parametrize("variant", ["p1d", "p2d", "p2d_tiles"])
def test_the_grabs_declared_are_the_chunks_a_run_deals(real_binaries: Path, tmp_path: Path,
                                                       variant: str) -> None:
    """The binary's --timing counts the chunks its dynamic loops dealt: as many as its
    declared grabs per step, times the steps."""
    binary = build_or_skip(variant) / variant
    n, steps = 300, 3
    scene = tmp_path / "scene.in"
    scene.write_text(f"{n} 1000 1 {steps}\nperf\n")
    done = subprocess.run([str(binary), "--threads", "2", "--timing", str(scene)],
                          capture_output=True, text=True, check=True, timeout=60)
    timing = json.loads(done.stderr.strip().splitlines()[-1])
    declared = default_registry()[variant].sync
    assert declared is not None
    assert sum(timing["threads_chunks"]) == declared.per_step(n)["grabs"] * steps


def sync_line(**changes: object) -> str:
    sync = {"regions": {"step": 1}, "nested_regions": {}, "barriers": {},
            "grabs": {"tile": 2}, "tile": 64, **changes}
    return json.dumps({**facts("v").__dict__, "sync": sync})


def test_a_sync_description_parses(tmp_path: Path) -> None:
    found = variants.describe(write_binary(tmp_path / "v", sync_line()))
    assert found.sync == SyncFacts(regions=Count(step=1),
                                            grabs=Count(tile=2), tile=64)
    assert found.sync.per_step(65)["grabs"] == 2 * 64  # rows 0..64: 64 rows of one tile


@pytest.mark.parametrize(("changes", "message"), [
    ({"grabs": {"chunk": 1}}, "'grabs' is no object of counts per step, row, pair, tile"),
    ({"regions": {"row": -1}}, "'regions' is no object of counts"),
    ({"regions": {"row": True}}, "'regions' is no object of counts"),
    ({"tile": 0}, "'tile' must be a count, at least 1 where a count is per tile"),
    ({"spin": {}}, "expected an object of regions, nested_regions, barriers, grabs and tile"),
])
def test_a_bad_sync_description_is_one_error(tmp_path: Path, changes: dict,
                                             message: str) -> None:
    binary = write_binary(tmp_path / "v", sync_line(**changes))
    with pytest.raises(HarnessError, match=re.escape(message)) as info:
        variants.describe(binary)
    assert str(binary) in str(info.value)
