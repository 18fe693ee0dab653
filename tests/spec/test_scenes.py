"""Scene points: random headers, the generator registry, generators, input files."""

from __future__ import annotations

import math

import pytest
from harness.errors import HarnessError
from harness.plan.cells import plan_cells
from harness.spec import scenes
from harness.spec.parse import load_config


def test_random_point_is_a_two_line_header() -> None:
    point = scenes.random_point(10000, 20000.0, 1.0, 50, "perf", 7)
    assert point.text == "10000 20000 1 50\nperf\n"
    assert point.label == "random" and point.seed == 7
    assert point.describe() == "n=10000 L=20000 r=1 S=50 seed=7"


@pytest.mark.parametrize(("value", "text"), [
    (20000.0, "20000"), (1.0, "1"), (0.5, "0.5"), (6324.555320336759, "6324.555320336759"),
    (1e7, "10000000"),
])
def test_format_real(value: float, text: str) -> None:
    assert scenes.format_real(value) == text
    assert float(text) == value


def test_builtin_generators_are_registered() -> None:
    assert {"lattice", "head_on", "corner"} <= set(scenes.REGISTRY.names())


@pytest.mark.parametrize("name", ["lattice", "head_on", "corner"])
def test_generators_write_valid_inputs(name: str) -> None:
    point = scenes.generated_point(name, {}, seed=1)
    n, L, r, steps, mode = scenes.parse_header(point.text, name)
    assert (n, L, r, steps, mode) == (point.n, point.L, point.r, point.steps, point.mode)
    rows = point.text.splitlines()[2:]
    assert len(rows) == n
    for i, row in enumerate(rows):
        index, x, y, vx, vy = row.split()
        assert int(index) == i
        assert r <= float(x) <= L - r and r <= float(y) <= L - r
        assert math.isfinite(float(vx)) and math.isfinite(float(vy))


def test_lattice_parameters() -> None:
    point = scenes.generated_point("lattice", {"n": 9, "L": 100.0, "r": 2.0}, seed=1)
    assert point.n == 9 and point.L == 100.0 and point.r == 2.0
    assert point.params == (("L", 100.0), ("n", 9), ("r", 2.0))
    with pytest.raises(HarnessError, match="do not fit"):
        scenes.generated_point("lattice", {"n": 10000, "L": 100.0, "r": 2.0}, seed=1)


def test_adding_a_generator_is_one_decorated_function() -> None:
    registry = scenes.GeneratorRegistry()

    @registry.register("pair_at_rest")
    def pair_at_rest(L: float = 50.0, r: float = 1.0, steps: int = 3,
                     mode: str = "print") -> scenes.ScenePoint:
        return scenes.make_scene(L, r, steps, mode, [(10.0, 10.0, 0.0, 0.0),
                                                     (20.0, 10.0, 0.0, 0.0)])

    info = registry.get("pair_at_rest")
    assert info.defaults == {"L": 50.0, "r": 1.0, "steps": 3, "mode": "print"}
    scene = info.fn(steps=4)
    assert scene.text.startswith("2 50 1 4\nprint\n0 10 10 0 0\n")
    with pytest.raises(ValueError, match="twice"):
        registry.register("pair_at_rest")(pair_at_rest)
    with pytest.raises(ValueError, match="needs a default"):
        registry.register("no_default")(lambda n: scenes.make_scene(1.0, 0.1, 1, "perf", []))


def test_generator_scene_in_config(write_config) -> None:
    path = write_config("variants: [seq]\nscene: {generator: head_on, gap: [2, 4], steps: 3}\n")
    plan = plan_cells(load_config(path))
    assert [c.scene.label for c in plan.cells] == ["head_on", "head_on"]
    assert [dict(c.scene.params)["gap"] for c in plan.cells] == [2.0, 4.0]
    assert all(c.scene.steps == 3 and c.scene.n == 2 for c in plan.cells)
    assert plan.cells[0].scene.input_sha256 != plan.cells[1].scene.input_sha256


def test_file_scene_relative_to_config(write_config, tmp_path) -> None:
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "two.in").write_text("2 100 1 4\nprint\n0 10 10 1 0\n1 20 10 -1 0\n")
    path = write_config("variants: [seq]\nscene: {file: scenes/two.in, seed: 3}\n")
    (cell,) = plan_cells(load_config(path)).cells
    assert cell.scene.label == "two.in"
    assert (cell.scene.n, cell.scene.L, cell.scene.r, cell.scene.steps) == (2, 100.0, 1.0, 4)
    assert cell.scene.mode == "print" and cell.scene.seed == 3


def test_parse_header_errors() -> None:
    with pytest.raises(HarnessError, match="header"):
        scenes.parse_header("2 100\n", "x.in")
    with pytest.raises(HarnessError, match="not 'N L r S'"):
        scenes.parse_header("two 100 1 4\nperf\n", "x.in")
    with pytest.raises(HarnessError, match="mode"):
        scenes.parse_header("2 100 1 4\nfast\n", "x.in")
