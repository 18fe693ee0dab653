"""The builds of a variant, named once: the double-precision default and the accuracy study's
others (the Makefile's BUILDS builds them: `make build/NAME-f32`, ...), with the unit
roundoff of the arithmetic each computes in. Names only: harness.spec.variants builds them."""

DEFAULT_BUILD = "f64"
TRUTH_BUILD = "f128"  # the accuracy study's truth: __float128
BUILDS: tuple[str, ...] = ("f64", "f32", "f128", "textbook", "report")
# Unit roundoff of the real type each build computes in (the formula builds are double).
UNIT_ROUNDOFF: dict[str, float] = {
    "f64": 2.0**-53, "f32": 2.0**-24, "f128": 2.0**-113, "textbook": 2.0**-53,
    "report": 2.0**-53,
}
DOUBLE_EPS = UNIT_ROUNDOFF[DEFAULT_BUILD]
# What each build computes in, in words (Markdown).
DESCRIPTIONS: dict[str, str] = {
    "f64": "double with SPEC's formula (`f64`)",
    "f32": "float (`f32`)",
    "f128": "__float128 (`f128`: the truth's own precision, so its shadow and divergence are "
            "zero by construction and only its invariants test it)",
    "textbook": "double with the textbook formula b·b − a·c, (−b − √disc)/a (`textbook`)",
    "report": "double with the report's discriminant and the (−b − √disc)/a root (`report`)",
}


def binary_name(variant: str, build: str) -> str:
    """build/NAME for the default build, build/NAME-BUILD for the others."""
    return variant if build == DEFAULT_BUILD else f"{variant}-{build}"


def unit_roundoff(build: str) -> float:
    """The unit roundoff of the build's arithmetic; a build the harness does not know (a
    custom binary) is taken as double."""
    return UNIT_ROUNDOFF.get(build, DOUBLE_EPS)
