"""Planning a config's cells: the grid, repeats, exclusions, exactness from the variants' own
facts, and the binaries a plan runs."""

from __future__ import annotations

from harness.plan.cells import is_exact, plan_cells
from harness.plan.cellstore import CellStore, checkout_tools, needed_binaries
from harness.repo import REPO_ROOT
from harness.spec.parse import load_config
from harness.spec.variants import VariantFacts, VariantRegistry, default_registry


def test_exactness(write_config) -> None:
    config = load_config(write_config(
        "variants: [seq, relative]\nbuilds: [f64, f32]\nscene: {n: 10, L: 100, r: 1, steps: 1}\n"
    ))
    registry = default_registry()
    assert is_exact(config, registry, "seq", "f64")
    assert not is_exact(config, registry, "seq", "f32")
    assert not is_exact(config, registry, "relative", "f64")


BASE = "variants: [seq, p1]\nscene: {n: [10, 20], L: 100, r: 1, steps: 1}\nthreads: [1, 2]\n"


def test_cells_come_scene_first_then_variant_and_threads(write_config) -> None:
    plan = plan_cells(load_config(write_config(BASE)))
    got = [(c.scene.n, c.threads, c.variant) for c in plan.cells]
    # seq, serial, is one cell a scene: at its first point
    assert got == [(10, 1, "seq"), (10, 1, "p1"), (10, 2, "p1"),
                   (20, 1, "seq"), (20, 1, "p1"), (20, 2, "p1")]


SERIAL = "variants: [seq, p1d]\nscene: {n: 10, L: 100, r: 1, steps: 1}\n"


def test_a_serial_variant_is_one_cell_a_scene_run_with_one_thread(write_config, tmp_path
                                                                  ) -> None:
    """Its --describe says parallel: false, so its cells at every thread count are one, run
    with one thread and keyed as a cell at one thread always was; a parallel one's are not."""
    plan = plan_cells(load_config(write_config(SERIAL + "threads: [1, 2, 3]\n")))
    assert [(c.variant, c.threads, c.ignored) for c in plan.cells] == [
        ("seq", 1, ("threads", "ranks")), ("p1d", 1, ("ranks",)), ("p1d", 2, ("ranks",)),
        ("p1d", 3, ("ranks",))]
    assert plan.cells[0].label.endswith("threads=1 (ignores threads)")
    alone = plan_cells(load_config(write_config(SERIAL + "threads: 2\n", "two")))
    assert [(c.variant, c.threads) for c in alone.cells] == [("seq", 1), ("p1d", 2)]
    one = plan_cells(load_config(write_config(SERIAL + "threads: 1\n", "one")))

    def key(plan):  # the seq cell's key, binaries not built
        store = CellStore(plan, REPO_ROOT, tmp_path / "results", "m1", assume_built=True)
        return store.cell_key(plan.cells[0])

    assert key(alone) == key(one) and key(alone).threads == 1
    # the rule follows the facts: a seq that said it was parallel would use its threads
    registry = VariantRegistry(facts=[VariantFacts("seq", "s", True, True, True),
                                      VariantFacts("p1d", "p", True, True, True)])
    config = load_config(write_config(SERIAL + "threads: [1, 2]\n", "facts"), registry)
    assert len(plan_cells(config, registry=registry).cells) == 4


def test_exclude_rules_name_the_config_s_thread_counts(write_config) -> None:
    """A rule sees the config's point: excluding seq at 2 threads leaves it at 1; at every
    count, nothing of it."""
    text = SERIAL + "threads: [1, 2]\nexclude: [{variant: seq, threads: %s}]\n"
    some = plan_cells(load_config(write_config(text % 2)))
    assert [(c.variant, c.threads) for c in some.cells] == [("seq", 1), ("p1d", 1), ("p1d", 2)]
    every = plan_cells(load_config(write_config(text % "[1, 2]", "every")))
    assert [(c.variant, c.threads) for c in every.excluded] == [("seq", 1), ("seq", 2)]
    assert "seq" not in {c.variant for c in every.cells}


def test_a_program_keeps_its_thread_counts(write_config) -> None:
    plan = plan_cells(load_config(write_config(
        "variants: [seq, mine]\nprograms: {mine: 'true {input} {threads}'}\n"
        "scene: {n: 10, L: 100, r: 1, steps: 1, seed: 1}\nthreads: [1, 2]\n")))
    assert [(c.variant, c.threads) for c in plan.cells] == [("seq", 1), ("mine", 1),
                                                             ("mine", 2)]


def test_excluded_cells_are_kept_apart(write_config) -> None:
    excluded = "exclude: [{variant: seq, threads_gt: 1}]\n"
    plan = plan_cells(load_config(write_config(BASE + excluded)))
    assert [(c.variant, c.threads) for c in plan.excluded] == [("seq", 2), ("seq", 2)]
    assert all(not (c.variant == "seq" and c.threads > 1) for c in plan.cells)


def test_quick_maps_points_onto_one_cell_once(write_config) -> None:
    plan = plan_cells(load_config(write_config(
        "variants: [seq]\nscene: {n: [500, 600], L: 1000, r: 1, steps: 9}\n")), quick=True)
    assert [(c.scene.n, c.scene.steps) for c in plan.cells] == [(400, 5)]


def test_a_variant_promises_exactness_and_a_custom_binary_does_not(write_config,
                                                                   tmp_path) -> None:
    program = tmp_path / "mine"
    program.write_text("#!/bin/sh\n")
    program.chmod(0o755)
    config = load_config(write_config(
        "variants: [seq, relative, mine]\nbinaries: {mine: mine}\n"
        "scene: {n: 10, L: 100, r: 1, steps: 1}\nvalidate: true\n"))
    cells = {c.variant: c for c in plan_cells(config).cells}
    assert cells["seq"].promises_exact and cells["seq"].exact
    assert not cells["relative"].promises_exact and not cells["relative"].exact
    assert not cells["mine"].promises_exact and cells["mine"].exact  # held to seq's output


def test_exactness_follows_the_registry_given(write_config) -> None:
    registry = VariantRegistry(facts=[
        VariantFacts("seq", "s", True, False, True), VariantFacts("p1", "p", False, True, True),
        VariantFacts("grid", "g", True, True, False)])
    config = load_config(write_config(BASE), registry)
    assert {c.variant: c.exact for c in plan_cells(config, registry=registry).cells} == {
        "seq": True, "p1": False}


def test_needed_binaries_add_seq_for_validation_and_the_checks_references(write_config) -> None:
    config = load_config(write_config(
        "variants: [p1]\nbuilds: [f32]\nscene: {n: 10, L: 100, r: 1, steps: 1}\n"
        "validate: {baseline: same}\nchecks: [invariants]\n"))
    names = [p.name for p in needed_binaries(plan_cells(config), REPO_ROOT / "build")]
    assert names == ["p1-f32", "seq-f32", "grid-f128", "seq", "peakrss"]


def test_openmp_costs_need_this_checkouts_ompcost_for_parallel_cells(write_config,
                                                                     tmp_path) -> None:
    """build/ompcost prices the machine's runtime, build/peakrss measures every cell's memory:
    both come from this checkout, also where an older revision's variants are measured (it
    may have no such tool), and only parallel variants' cells run ompcost."""
    config = load_config(write_config(
        "variants: [seq, p2]\nscene: {n: 10, L: 100, r: 1, steps: 1}\nopenmp_costs: true\n"))
    revision = tmp_path / "revision" / "build"
    needed = needed_binaries(plan_cells(config), revision)
    tools = [REPO_ROOT / "build" / "ompcost", REPO_ROOT / "build" / "peakrss"]
    assert needed == [revision / "seq", revision / "p2", *tools]
    assert checkout_tools(needed) == tools
    serial = load_config(write_config(
        "variants: [seq]\nscene: {n: 10, L: 100, r: 1, steps: 1}\nopenmp_costs: true\n",
        "serial"))
    assert checkout_tools(needed_binaries(plan_cells(serial), revision)) == tools[1:]
