"""The names machines go by wherever results show them (a page, its links, the tables,
compare's output), from their stored descriptions (<experiment>/machines/<machine_id>.json):
each machine's own label ("AMD EPYC (znver3) x2"), and where machines share one, what tells
them apart among them, in this order: the compiler's target, AVX-512, cores, memory, the
microarchitecture; the start of the id only where nothing else does. Standard library only."""

from collections.abc import Callable, Iterable, Mapping
from pathlib import Path

from harness.store import layout
from harness.store.records import MACHINE_KEY, read_json

SHORT_ID = 8  # hex digits of a machine id that tell machines apart when nothing else does
Described = Mapping[str, object]

# AMD's families and model ranges by microarchitecture (their own published numbers); a CPU
# not listed is named by its family and model.
AMD_CORES: tuple[tuple[int, range, str], ...] = (
    (23, range(0x00, 0x30), "Zen/Zen+"), (23, range(0x30, 0x100), "Zen 2"),
    (25, range(0x00, 0x10), "Zen 3"), (25, range(0x10, 0x20), "Zen 4"),
    (25, range(0x20, 0x60), "Zen 3"), (25, range(0x60, 0x80), "Zen 4"),
    (25, range(0xA0, 0xB0), "Zen 4c"), (26, range(0x00, 0x100), "Zen 5"),
)


def _int(value: object) -> int | None:
    return value if isinstance(value, int) and not isinstance(value, bool) else None


def microarchitecture(described: Described) -> str:
    """`Zen 4`, or `family 6 model 143` where the vendor's numbers are not listed here."""
    family, model = _int(described.get("family")), _int(described.get("model"))
    if family is None or model is None:
        return ""
    if described.get("vendor") == "AuthenticAMD":
        for known, models, name in AMD_CORES:
            if family == known and model in models:
                return name
    return f"family {family} model {model}"


def _avx512(described: Described) -> str:
    isa = described.get("isa")
    if not isinstance(isa, list):
        return ""
    return "AVX-512" if "avx512f" in isa else "no AVX-512"


def _cores(described: Described) -> str:
    cores = _int(described.get("cores"))
    return f"{cores} cores" if cores else ""


def _memory(described: Described) -> str:
    memory = described.get("memory_gib")
    return f"{memory} GiB" if isinstance(memory, int | float) else ""


def _target(described: Described) -> str:
    march = described.get("march")
    return f"-march={march}" if isinstance(march, str) and march else ""


# What tells machines apart, in the order it is added to their labels.
TRAITS: tuple[Callable[[Described], str], ...] = (_target, _avx512, _cores, _memory,
                                                   microarchitecture)


def base_label(described: Described) -> str:
    label = described.get("label")
    if isinstance(label, str) and label:
        return label
    name = described.get("model_name")
    return str(name) if name else "machine"


def machine_labels(machines: Mapping[str, Described]) -> dict[str, str]:
    """Each machine's label, with the traits that tell it from others of that label."""
    names = {mid: base_label(d) for mid, d in machines.items()}
    groups: dict[str, list[str]] = {}
    for mid, name in names.items():
        groups.setdefault(name, []).append(mid)
    for members in groups.values():  # a machine alone in its group keeps its label as it is
        extra = {mid: [] for mid in members}  # type: dict[str, list[str]]
        for trait in TRAITS:
            values = {mid: trait(machines[mid]) for mid in members}
            if len(set(values.values())) > 1:
                for mid in members:
                    extra[mid].append(values[mid] or "?")
            seen = [tuple(extra[m]) for m in members]
            if len(set(seen)) == len(seen):
                break
        for mid in members:
            if seen.count(tuple(extra[mid])) > 1:
                extra[mid].append(mid[:SHORT_ID])
            names[mid] = ", ".join([names[mid], *extra[mid]])
    return names


def read_machines(directories: Iterable[Path]) -> dict[str, Described]:
    """The machines described under experiment directories (machines/<machine_id>.json, and
    env.json for results from before those), by id."""
    found: dict[str, Described] = {}
    for directory in directories:
        exp = layout.ExperimentDir(directory)
        paths = sorted(exp.path.joinpath(layout.MACHINES).glob(f"*{layout.RECORD_SUFFIX}"))
        for path in (exp.env_json, *paths):
            env = read_json(path)
            if not isinstance(env, dict) or not isinstance(env.get("machine"), dict):
                continue
            mid = str(env.get(MACHINE_KEY) or env["machine"].get(MACHINE_KEY) or "")
            if mid:
                found[mid] = env["machine"]
    return found
