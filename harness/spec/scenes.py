"""Scenes: the input a variant reads (SPEC section 1) and the named generators that write it.

A scene point is one concrete input. It is random (only the header: the binaries draw the
particles from --seed, SPEC section 4), written by a named generator, or read from a file.
Adding a generator is one decorated function:

    @generator("name")
    def name(n: int = 10, L: float = 100.0, r: float = 1.0, steps: int = 10,
             mode: str = "perf") -> ScenePoint:
        return make_scene(L, r, steps, mode, [(x, y, vx, vy), ...])

Its keyword parameters (with defaults; their types are those of the defaults) are the keys
a config may set under `scene:`, each one a value or a list of values to sweep.
"""

import dataclasses
import functools
import hashlib
import inspect
import math
import random
import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from harness.errors import HarnessError, describe_value

MODES = ("print", "perf")
DEFAULT_MODE = "perf"
DEFAULT_SEED = 1
RANDOM_SCENE = "random"
REAL_FORMAT = "%.17g"

Particle = tuple[float, float, float, float]

# What the binaries accept (SPEC section 1; variants/core): the harness refuses an input past
# these first, at load time.
MAX_N = 2**31 - 1
MAX_STEPS = 2**63 - 1
PRINT_LINE_MIN_BYTES = 48  # the shortest line print mode writes
MAX_OUTPUT_BYTES = 2**63 - 1  # the largest file
# An input's tokens as the binaries read them: an ASCII integer, a decimal real (strtod's,
# without its hexadecimal form; "nan" and "inf" are read, then refused as not finite).
INT_TOKEN = re.compile(r"[+-]?[0-9]+")
REAL_TOKEN = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"
                        r"|[+-]?(?:inf|infinity|nan)", re.IGNORECASE)
# Digits past these cannot be in range (and Python refuses to convert 4300 of them).
MAX_INT_TOKEN_CHARS = 21


@dataclass(frozen=True)
class ScenePoint:
    """One concrete input of a cell, with the parameters the results table reports."""

    label: str  # "random", the generator name ("" until named), or the input file's name
    n: int
    L: float
    r: float
    steps: int
    mode: str
    seed: int
    text: str
    params: tuple[tuple[str, object], ...] = ()

    # Asked for by every cell of the scene, and a program's scene lists every particle: hashed
    # once (a frozen dataclass without slots keeps it in __dict__, out of eq and hash).
    @functools.cached_property
    def input_sha256(self) -> str:
        return hashlib.sha256(self.text.encode()).hexdigest()

    def describe(self) -> str:
        """A short human label, e.g. `n=10000 L=20000 r=1 S=50` (plus the generator)."""
        head = "" if self.label == RANDOM_SCENE else f"{self.label} "
        extra = "".join(f" {k}={format_number(v)}" for k, v in self.params
                        if k not in ("n", "L", "r", "steps", "mode"))
        mode = "" if self.mode == DEFAULT_MODE else f" {self.mode}"
        return (f"{head}n={self.n} L={format_number(self.L)} r={format_number(self.r)} "
                f"S={self.steps}{mode} seed={self.seed}{extra}")


def format_number(value: object) -> str:
    """Compact rendering of an axis value for labels: 20000.0 -> 20000, 1e7 -> 1e+07."""
    return f"{value:g}" if isinstance(value, float) else str(value)


def format_real(value: float) -> str:
    """A real for an input file header: integral values without a fraction, else round-trip."""
    if float(value).is_integer() and abs(value) < 1e15:
        return str(int(value))
    return repr(float(value))


def header_text(n: int, L: float, r: float, steps: int, mode: str) -> str:
    return f"{n} {format_real(L)} {format_real(r)} {steps}\n{mode}\n"


def particle_row(index: int, particle: Particle) -> str:
    """One particle line of an input: `i x y vx vy`, each real round-trip exact."""
    return f"{index} " + " ".join(REAL_FORMAT % value for value in particle) + "\n"


def make_scene(L: float, r: float, steps: int, mode: str, particles: Iterable[Particle],
               n: int | None = None) -> ScenePoint:
    """What a generator returns: an input with the given particles as indices 0.. (n > len
    lets the rest be random), its label and seed given by the registry."""
    rows = [particle_row(i, particle) for i, particle in enumerate(particles)]
    total = len(rows) if n is None else n
    return ScenePoint("", total, float(L), float(r), steps, mode, DEFAULT_SEED,
                      header_text(total, L, r, steps, mode) + "".join(rows))


def random_point(n: int, L: float, r: float, steps: int, mode: str, seed: int) -> ScenePoint:
    """A scene the binaries generate from the seed: a two-line input."""
    return ScenePoint(RANDOM_SCENE, n, float(L), float(r), steps, mode, seed,
                      header_text(n, L, r, steps, mode))


# --- every particle listed ---------------------------------------------------------------

# SPEC section 4's generator: splitmix64 and the draws of one particle.
SPLITMIX_GAMMA = 0x9E3779B97F4A7C15
SPLITMIX_MUL1 = 0xBF58476D1CE4E5B9
SPLITMIX_MUL2 = 0x94D049BB133111EB
TWO_PI = 2.0 * math.pi  # the double nearest 2*pi, as the C literal rounds
DRAWS_PER_PARTICLE = 4


def uniforms(seed: int, count: int) -> np.ndarray:
    """The first `count` doubles in [0, 1) of the splitmix64 stream that starts at `seed`."""
    steps = np.arange(1, count + 1, dtype=np.uint64)
    with np.errstate(over="ignore"):  # modulo 2^64, as in C
        z = np.uint64(seed) + steps * np.uint64(SPLITMIX_GAMMA)
        z = (z ^ (z >> np.uint64(30))) * np.uint64(SPLITMIX_MUL1)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(SPLITMIX_MUL2)
        z = z ^ (z >> np.uint64(31))
    return (z >> np.uint64(11)).astype(np.float64) * 2.0**-53


def generate(count: int, L: float, r: float, seed: int) -> list[Particle]:
    """The first `count` particles the binaries draw for unlisted indices (SPEC section 4),
    bit for bit: the same operations in IEEE double, and the C library's cos and sin."""
    u = uniforms(seed, DRAWS_PER_PARTICLE * count).reshape(count, DRAWS_PER_PARTICLE)
    a, b = L / (8 * r), L / 4
    lo, hi = min(a, b), max(a, b)
    x = r + u[:, 0] * (L - 2 * r)
    y = r + u[:, 1] * (L - 2 * r)
    speed = lo + u[:, 2] * (hi - lo)
    angle = TWO_PI * u[:, 3]
    return [(float(px), float(py), s * math.cos(t), s * math.sin(t))
            for px, py, s, t in zip(x, y, speed.tolist(), angle.tolist(), strict=True)]


def with_every_particle(point: ScenePoint) -> ScenePoint:
    """The scene with every particle listed in its input: the ones it lists as written, the
    others drawn as the binaries would draw them from its seed."""
    n, _, _, _, _ = parse_header(point.text, point.label)
    tokens = point.text.split()
    body = tokens[5:]
    if len(body) % 5:
        raise HarnessError(f"{point.label}: particle lines must have 5 fields (i x y vx vy)")
    listed: dict[int, str] = {}
    for k in range(0, len(body), 5):
        try:
            index = parse_int(body[k])
        except ValueError:
            raise HarnessError(f"{point.label}: particle index {describe_value(body[k])} is "
                               "not an integer") from None
        if not 0 <= index < n or index in listed:
            raise HarnessError(f"{point.label}: particle index {index}: expected a new index "
                               f"in [0, {n})")
        listed[index] = " ".join(body[k:k + 5]) + "\n"
    missing = [i for i in range(n) if i not in listed]
    if not missing:
        return point
    drawn = generate(len(missing), point.L, point.r, point.seed)
    listed.update((i, particle_row(i, p)) for i, p in zip(missing, drawn, strict=True))
    rows = "".join(listed[i] for i in sorted(listed))
    head = " ".join(tokens[:4]) + "\n" + tokens[4] + "\n"
    return dataclasses.replace(point, text=head + rows)


def with_run(point: ScenePoint, steps: int, mode: str) -> ScenePoint:
    """The scene with another step count and mode (L and r kept as written)."""
    tokens = point.text.split(maxsplit=5)
    rest = tokens[5] if len(tokens) > 5 else ""
    text = f"{tokens[0]} {tokens[1]} {tokens[2]} {steps}\n{mode}\n{rest}"
    return dataclasses.replace(point, steps=steps, mode=mode, text=text)


# --- the generator registry -------------------------------------------------------------

GeneratorFn = Callable[..., ScenePoint]


@dataclass(frozen=True)
class GeneratorInfo:
    fn: GeneratorFn
    defaults: Mapping[str, object]  # parameter -> default value (its type is the param's)
    doc: str


class GeneratorRegistry(dict[str, GeneratorInfo]):
    """Named scene generators; filled once, at import, by the @generator decorator."""

    def register(self, name: str) -> Callable[[GeneratorFn], GeneratorFn]:
        def decorate(fn: GeneratorFn) -> GeneratorFn:
            if name in self:
                raise ValueError(f"scene generator {name!r} registered twice")
            defaults: dict[str, object] = {}
            for param in inspect.signature(fn).parameters.values():
                if param.default is inspect.Parameter.empty:
                    raise ValueError(f"generator {name!r}: {param.name!r} needs a default")
                defaults[param.name] = param.default
            self[name] = GeneratorInfo(fn, defaults, inspect.getdoc(fn) or "")
            return fn

        return decorate

    def names(self) -> tuple[str, ...]:
        return tuple(sorted(self))

    def __missing__(self, name: str) -> GeneratorInfo:
        raise HarnessError(f"unknown scene generator {name!r}")


REGISTRY = GeneratorRegistry()
generator = REGISTRY.register


def generated_point(name: str, params: Mapping[str, object], seed: int) -> ScenePoint:
    """Run generator `name` with `params` (already type-checked by the config loader)."""
    scene = REGISTRY[name].fn(**params)
    check_scene(scene.n, scene.L, scene.r, scene.steps, scene.mode, f"generator {name!r}")
    return dataclasses.replace(scene, label=name, seed=seed, params=tuple(sorted(params.items())))


def read_text(source: Path, what: str, max_bytes: int | None = None) -> str:
    """A file's UTF-8 text; a HarnessError naming the file (`what` says what it is) when it is
    missing, unreadable, larger than max_bytes or not UTF-8."""
    try:
        if max_bytes is not None and source.stat().st_size > max_bytes:
            raise HarnessError(f"{source}: {what} of {source.stat().st_size} bytes is larger "
                               f"than {max_bytes}")
        data = source.read_bytes()
    except FileNotFoundError:
        raise HarnessError(f"{source}: no such {what}") from None
    except OSError as exc:
        raise HarnessError(f"{source}: cannot read {what}: {exc.strerror}") from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise HarnessError(f"{source}: {what} is not UTF-8 text: byte 0x{data[exc.start]:02x} "
                           f"on line {line} (offset {exc.start})") from None


def file_point(path: Path, seed: int) -> ScenePoint:
    """A scene read from an input file, its header checked as the binaries check it."""
    text = read_text(path, "scene file")
    n, L, r, steps, mode = parse_header(text, str(path))
    check_scene(n, L, r, steps, mode, str(path))
    return ScenePoint(path.name, n, L, r, steps, mode, seed, text)


def parse_int(token: str) -> int:
    """An integer token as the binaries read it; ValueError otherwise."""
    if len(token) > MAX_INT_TOKEN_CHARS or not INT_TOKEN.fullmatch(token):
        raise ValueError(token)
    return int(token)


def parse_real(token: str) -> float:
    """A real token as the binaries read it (not necessarily finite); ValueError otherwise."""
    if not REAL_TOKEN.fullmatch(token):
        raise ValueError(token)
    return float(token)


def parse_header(text: str, where: str) -> tuple[int, float, float, int, str]:
    """The first five tokens of an input: N L r S MODE."""
    tokens = text.split(maxsplit=5)[:5]
    if len(tokens) < 5:
        raise HarnessError(f"{where}: input header must be 'N L r S' then a MODE line")
    try:
        n, steps = parse_int(tokens[0]), parse_int(tokens[3])
        L, r = parse_real(tokens[1]), parse_real(tokens[2])
    except ValueError:
        header = describe_value(" ".join(tokens[:4]))
        raise HarnessError(f"{where}: input header {header} is not 'N L r S'") from None
    if tokens[4] not in MODES:
        raise HarnessError(f"{where}: input mode {describe_value(tokens[4])} is not one of "
                           f"{', '.join(MODES)}")
    return n, L, r, steps, tokens[4]


def scene_problem(n: int, L: float, r: float, steps: int, mode: str) -> str | None:
    """What is wrong with a header by SPEC section 1's rules and the binaries' bounds, as the
    binaries say it, or None when they would accept it."""
    if not 0 <= n <= MAX_N:
        return f"N={n} is outside [0, {MAX_N}]"
    if not math.isfinite(L):
        return f"L={L}: expected a finite real"
    if not (math.isfinite(r) and r > 0):
        return f"r={r}: expected r > 0"
    if not 2 * r <= L:
        return f"r={r:g}: expected 2r <= L (L={L:g})"
    if not math.isfinite(L / (8 * r)):
        return f"r={r:g}: the generated speed L/(8r) is not finite (L={L:g})"
    if not 0 <= steps <= MAX_STEPS:
        return f"S={steps} is outside [0, {MAX_STEPS}]"
    if mode not in MODES:
        return f"MODE {describe_value(mode)} is not one of {', '.join(MODES)}"
    if mode == "print" and n * (steps + 1) * PRINT_LINE_MIN_BYTES > MAX_OUTPUT_BYTES:
        return (f"print mode with N={n} and S={steps} writes more than a file can hold "
                "(2^63 bytes)")
    return None


def check_scene(n: int, L: float, r: float, steps: int, mode: str, where: str) -> None:
    problem = scene_problem(n, L, r, steps, mode)
    if problem is not None:
        raise HarnessError(f"{where}: invalid scene: {problem}")


# --- generators ---------------------------------------------------------------------------


@generator("lattice")
def lattice(n: int = 100, L: float = 1000.0, r: float = 1.0, steps: int = 10,
            mode: str = "perf", speed: float = 10.0) -> ScenePoint:
    """n discs on a square lattice; rows move alternately right/left and up/down at `speed`."""
    side = max(1, math.ceil(math.sqrt(n)))
    spacing = (L - 2 * r) / side
    if spacing < 2 * r:
        raise HarnessError(f"generator 'lattice': {n} discs of radius {r} do not fit in L={L}")
    diagonal = speed / math.sqrt(2.0)
    particles = []
    for k in range(n):
        row, col = divmod(k, side)
        x = r + spacing * (col + 0.5)
        y = r + spacing * (row + 0.5)
        vx = diagonal if row % 2 == 0 else -diagonal
        vy = diagonal if col % 2 == 0 else -diagonal
        particles.append((x, y, vx, vy))
    return make_scene(L, r, steps, mode, particles)


# The dense slow scene: discs moving about a radius a step, where the binaries' own
# generator gives speeds of L/(8r) to L/4 (SPEC section 4), so a box this crowded would see
# every disc cross it in a few steps.
DENSE_SLOW_SPEEDS = (0.5, 1.5)  # radii per step
DENSE_SLOW_SEED = 1


@generator("dense_slow")
def dense_slow(n: int = 1000, L: float = 200.0, r: float = 1.0, steps: int = 10,
               mode: str = "perf") -> ScenePoint:
    """n discs placed uniformly in the box (overlaps at the start allowed: overlapping pairs
    pass through, SPEC section 1), each moving 0.5-1.5 radii a step in a uniform direction."""
    rng = random.Random(DENSE_SLOW_SEED)
    particles = []
    for _ in range(n):
        speed = r * rng.uniform(*DENSE_SLOW_SPEEDS)
        angle = rng.uniform(0.0, 2.0 * math.pi)
        x, y = rng.uniform(r, L - r), rng.uniform(r, L - r)
        particles.append((x, y, speed * math.cos(angle), speed * math.sin(angle)))
    return make_scene(L, r, steps, mode, particles)


@generator("head_on")
def head_on(L: float = 100.0, r: float = 1.0, steps: int = 10, mode: str = "perf",
            gap: float = 10.0, speed: float = 2.0) -> ScenePoint:
    """Two discs on the horizontal midline, `gap` apart (surface to surface), moving at each
    other at `speed`: one head-on pair collision, then wall bounces."""
    mid = L / 2
    half = r + gap / 2
    if mid - half < r:
        raise HarnessError(f"generator 'head_on': gap {gap} does not fit in L={L} with r={r}")
    particles = [(mid - half, mid, speed, 0.0), (mid + half, mid, -speed, 0.0)]
    return make_scene(L, r, steps, mode, particles)


@generator("corner")
def corner(L: float = 100.0, r: float = 1.0, steps: int = 10, mode: str = "perf",
           speed: float = 7.0) -> ScenePoint:
    """One disc on the diagonal flying into the top-right corner: both axes hit at once."""
    start = L / 2
    diagonal = speed / math.sqrt(2.0)
    return make_scene(L, r, steps, mode, [(start, start, diagonal, diagonal)])

