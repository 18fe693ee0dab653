# collide-bench: build every variant into build/, test, benchmark, set up the environment.
#
#   make all              every variant, double precision: build/seq build/p1 ... build/grid,
#                         build/ompcost (the OpenMP runtime's cost of a region, a barrier,
#                         a dynamic chunk at a thread count: tools/ompcost.c) and build/peakrss
#                         (a command's peak resident memory: tools/peakrss.c)
#   make build/seq-f32    any variant in float; -f128 in __float128; -textbook / -report with
#                         the other pair-time formulas (the accuracy study's builds)
#   make portable         every variant for baseline x86-64 (no AVX) into build/portable/
#   make lane             every variant for x86-64-v3 (no AVX-512) into build/lane/: what the
#                         instruction lane counts under cachegrind
#   make test-c           C tests: unit tests (optimised, ASan+UBSan, portable) and scene scripts
#   make test             test-c, ruff and the Python tests, side by side
#   make bench            the performance configs (BENCH_CONFIGS, default configs/bench-core,
#                         bench-grid and relative) measured by the harness's run into
#                         results/<name>/ and rendered into report/; BENCH_CONFIGS="$$(ls
#                         configs/bench-*.yaml) configs/relative.yaml" adds the million,
#                         the dense scene and the grading benchmark
#   make fuzz             fuzz the config loader and the binaries' input reader (ASan builds)
#                         for FUZZ_SECONDS (default 600); make test runs a few seconds of it
#   make setup            Python environment (.venv) and hyperfine: what the harness needs
#   make setup-test       setup, and what only the tests need (requirements-test.txt; as root,
#                         Debian's Slurm and chromium); make test runs it first
#   make quickstart       setup, build, run configs/quickstart.yaml and render report/
#   make publish          the project's published measurements (published/results, committed):
#                         PUBLISH_CONFIGS (default: the config of every published experiment)
#                         measured on this machine, published/report rendered from every
#                         machine's; make publish-report renders it only
#
# A variant is a file variants/NAME.c, with, if it is split into pieces, the files
# variants/NAME/*.c and its own headers variants/NAME/*.h; adding one needs no change here.
# Two things a variant's source says for itself:
#   - a variant that includes another variant's header (#include "OTHER/....h") links OTHER's
#     pieces too (every variants/OTHER/*.c, compiled as for OTHER): mpi uses grid's finder so;
#   - a variant that includes <mpi.h> is an MPI variant: its own files are compiled and it is
#     linked with MPICC (default mpicc; the core and the pieces it borrows stay $(CC) objects),
#     and it is built, listed by print-variants and tested only where MPICC is found (without
#     it, `make all` leaves it out and succeeds).

.DEFAULT_GOAL := all
SHELL := /bin/bash

MPICC ?= mpicc
# The MPI variants (their file includes <mpi.h>), and whether MPICC is here to build them.
MPI_VARIANTS := $(sort $(basename $(notdir $(shell grep -l '^\#include <mpi\.h>' variants/*.c))))
HAVE_MPICC := $(shell command -v $(MPICC) 2>/dev/null)
VARIANTS := $(filter-out $(if $(HAVE_MPICC),,$(MPI_VARIANTS)), \
                         $(sort $(basename $(notdir $(wildcard variants/*.c)))))
CORE_SRC := $(wildcard variants/core/*.c)
HEADERS := $(wildcard variants/core/*.h)
# A variant NAME is built from variants/NAME.c and every variants/NAME/*.c, and the pieces of
# the variants whose headers it includes (BORROWED); its headers in variants/NAME/ and theirs
# are prerequisites of all of its objects. $(1) is NAME or NAME/PIECE.
VARIANT_NAME = $(firstword $(subst /, ,$(1)))
VARIANT_DIR = variants/$(call VARIANT_NAME,$(1))
BORROWED = $(filter-out core $(1),$(if $(wildcard variants/$(1).c),$(shell sed -n \
           's|^\#include "\([A-Za-z0-9_]*\)/[^"]*".*|\1|p' variants/$(1).c)))
VARIANT_HEADERS = $(wildcard $(call VARIANT_DIR,$(1))/*.h \
                  $(patsubst %,variants/%/*.h,$(call BORROWED,$(call VARIANT_NAME,$(1)))))
# The objects of variant $(2)'s pieces (variants/$(2)/*.c, and those it borrows) in the object
# directory $(1).
VARIANT_PIECES = $(patsubst variants/%.c,build/obj/$(1)/%.o,$(wildcard variants/$(2)/*.c \
                 $(patsubst %,variants/%/*.c,$(call BORROWED,$(2)))))
# The compiler of variant $(1)'s own objects and of its binary: MPICC for an MPI variant.
CC_OF = $(if $(filter $(call VARIANT_NAME,$(1)),$(MPI_VARIANTS)),$(MPICC),$(CC))
PYTHON := .venv/bin/python
# Written by `scripts/setup.sh --test` once the tests' tools are installed.
TEST_READY := .venv/.test-ready

# Exact builds: IEEE double evaluated as written. No FMA contraction, never -ffast-math: the
# variants must agree byte for byte, and SPEC fixes the order of every operation.
EXACT := -std=c11 -ffp-contract=off -fno-fast-math
OPT ?= -O3 -march=native
WARN := -Wall -Wextra -Wpedantic -Werror
SANITIZE := -O1 -g -fno-omit-frame-pointer -fsanitize=address,undefined,float-cast-overflow \
            -fno-sanitize-recover=all
BASE_CFLAGS = $(EXACT) $(OPT) $(WARN) -fopenmp -D_POSIX_C_SOURCE=200809L
BASE_LDLIBS = -lm

# The builds beside the default double one: name, compile flags, libraries.
FLAGS_f32 := -DSIM_REAL_F32
FLAGS_f128 := -DSIM_REAL_F128
LIBS_f128 := -lquadmath
FLAGS_textbook := -DSIM_PAIR_TEXTBOOK
FLAGS_report := -DSIM_PAIR_REPORT
BUILDS := f32 f128 textbook report

# Variant objects and binaries list their own headers and pieces through a second expansion
# of $*.
.SECONDEXPANSION:

# $(1) object directory, $(2) binary pattern, $(3) extra compile flags, $(4) extra libraries.
define build_rules
build/obj/$(1)/core/%.o: variants/core/%.c $$(HEADERS)
	@mkdir -p $$(@D)
	$$(CC) $$(BASE_CFLAGS) $(3) $$(CFLAGS) -c $$< -o $$@
build/obj/$(1)/%.o: variants/%.c $$(HEADERS) $$$$(call VARIANT_HEADERS,$$$$*)
	@mkdir -p $$(@D)
	$$(call CC_OF,$$*) $$(BASE_CFLAGS) $(3) $$(CFLAGS) -c $$< -o $$@
$(2): build/obj/$(1)/%.o $$$$(call VARIANT_PIECES,$(1),$$$$*) \
      $$(patsubst variants/core/%.c,build/obj/$(1)/core/%.o,$$(CORE_SRC))
	@mkdir -p $$(@D)
	$$(call CC_OF,$$*) $$(BASE_CFLAGS) $(3) $$(CFLAGS) $$^ -o $$@ $$(BASE_LDLIBS) $(4) $$(LDLIBS)
endef

$(eval $(call build_rules,f64,build/%,,))
$(foreach b,$(BUILDS),$(eval $(call build_rules,$(b),build/%-$(b),$(FLAGS_$(b)),$(LIBS_$(b)))))
$(eval $(call build_rules,asan,build/asan/%,$(SANITIZE),))
# The portable build: baseline x86-64 (SSE2, no AVX), what `make all OPT=-O3` gives on Debian
# (docs/slurm.md: Slurm on mixed nodes). Its vector paths are others than -march=native's (grid's
# 4-lane prefilter, the core's 16-byte motion lanes), so the tests run it too.
PORTABLE := $(if $(filter x86_64 i%86,$(shell uname -m)),-march=x86-64 -mtune=generic,)
$(eval $(call build_rules,portable,build/portable/%,$(PORTABLE),))
# The instruction lane's build (harness.plan.lane): x86-64-v3 (AVX2, no AVX-512), which
# Valgrind's cachegrind can run, and one instruction set on every machine, so that counts of
# two machines compare. Each build of BUILDS has its lane twin, build/lane/NAME-BUILD.
LANE := $(if $(filter x86_64,$(shell uname -m)),-march=x86-64-v3 -mtune=generic,)
$(eval $(call build_rules,lane,build/lane/%,$(LANE),))
$(foreach b,$(BUILDS),$(eval $(call build_rules,lane-$(b),build/lane/%-$(b),$(LANE) $(FLAGS_$(b)),$(LIBS_$(b)))))

# Keep the objects: they are prerequisites of many binaries.
.SECONDARY:

.PHONY: all asan portable lane fuzz test test-c test-c-unit test-c-scenes test-c-scenes-asan test-c-portable test-python lint bench setup setup-test quickstart publish publish-report clean print-flags print-variants print-builds

all: $(addprefix build/,$(VARIANTS)) build/ompcost build/peakrss

# The measuring tools beside the variants (no variant: no core, no --describe).
build/ompcost: tools/ompcost.c
	@mkdir -p $(@D)
	$(CC) $(BASE_CFLAGS) $(CFLAGS) $< -o $@ $(BASE_LDLIBS) $(LDLIBS)

# No OpenMP and no libm: the commands it runs are forked from its few pages (tools/peakrss.c).
build/peakrss: tools/peakrss.c
	@mkdir -p $(@D)
	$(CC) -std=c11 -O2 $(WARN) -D_DEFAULT_SOURCE $(CFLAGS) $< -o $@

asan: $(addprefix build/asan/,$(VARIANTS))

portable: $(addprefix build/portable/,$(VARIANTS))

lane: $(addprefix build/lane/,$(VARIANTS))

print-flags:
	@echo "$(CC) $(BASE_CFLAGS) $(CFLAGS)"

print-variants:
	@echo "$(VARIANTS)"

print-builds:
	@echo "$(BUILDS)"

# ---- tests ----
C_TESTS := $(sort $(basename $(notdir $(wildcard tests/c/test_*.c))))
CORE_LIB_SRC := $(filter-out variants/core/sim_main.c,$(CORE_SRC))

# Tests include tests/c/check.h, and a single-file variant's source (test_relative.c includes
# variants/relative.c). tests/c/test_NAME.c of a variant split into pieces (variants/NAME/*.c)
# links that variant's objects instead and includes its headers.
TEST_INCLUDES := $(wildcard variants/*.c) $(wildcard variants/*/*.h) $(wildcard tests/c/*.h)
# The variant objects test $(2) (test_NAME) links, from the object directory $(1): NAME's, when
# NAME is a variant with pieces; none otherwise.
TEST_VARIANT_OBJS = $(if $(wildcard variants/$(2:test_%=%).c), \
                    $(if $(call VARIANT_PIECES,$(1),$(2:test_%=%)), \
                    build/obj/$(1)/$(2:test_%=%).o $(call VARIANT_PIECES,$(1),$(2:test_%=%))))

# $(1) object directory, $(2) test directory, $(3) extra compile flags.
define test_rules
build/$(2)/%: tests/c/%.c $$(patsubst variants/core/%.c,build/obj/$(1)/core/%.o,$$(CORE_LIB_SRC)) \
              $$$$(call TEST_VARIANT_OBJS,$(1),$$$$*) $$(HEADERS) $$(TEST_INCLUDES)
	@mkdir -p $$(@D)
	$$(CC) $$(BASE_CFLAGS) $(3) -Ivariants/core $$(CFLAGS) $$< $$(filter %.o,$$^) -o $$@ $$(BASE_LDLIBS)
endef

$(eval $(call test_rules,f64,tests,))
$(eval $(call test_rules,asan,tests-asan,$(SANITIZE)))
# TEST_PORTABLE: the portable unit tests check what their numeric code decides (test_grid).
$(eval $(call test_rules,portable,tests-portable,$(PORTABLE) -DTEST_PORTABLE))

SCENE_SCRIPTS := $(sort $(wildcard tests/c/*_scenes.sh))

# The C tests in four groups that make runs side by side: the unit tests of the optimised,
# sanitizer and portable builds; every scene script against the optimised build, and against
# the sanitizer build; run_scenes.sh (every exact variant against seq at 1 and 2 threads, the
# parts the compiler's code for the numeric loops decides) against the portable build.
C_TEST_GROUPS := test-c-unit test-c-scenes test-c-scenes-asan test-c-portable

# The unit tests run teams of 2 to 8 threads through thousands of short regions (test_grid:
# every scene at 1-4 and 8 threads): with the default wait policy a waiting thread spins while
# the one it waits for is off its core (2 cores, the other groups beside it): passive waiting
# took the unit tests from about 400 to about 105 s of CPU. The results do not depend on the
# policy; the scene scripts run every variant with the default one.
test-c-unit: $(addprefix build/tests/,$(C_TESTS)) $(addprefix build/tests-asan/,$(C_TESTS)) $(addprefix build/tests-portable/,$(C_TESTS))
	@set -e; for t in $(C_TESTS); do for d in tests tests-asan tests-portable; do echo "== $$t ($$d)"; OMP_WAIT_POLICY=passive build/$$d/$$t; done; done

test-c-scenes: all build/seq-f32 build/seq-f128
	@set -e; for s in $(SCENE_SCRIPTS); do echo "== $$s build"; bash $$s build; done

test-c-scenes-asan: asan
	@set -e; for s in $(SCENE_SCRIPTS); do echo "== $$s build/asan"; bash $$s build/asan; done

test-c-portable: portable
	@echo "== tests/c/run_scenes.sh build/portable"; bash tests/c/run_scenes.sh build/portable

test-c: $(C_TEST_GROUPS)

# pytest in two processes side by side: the Slurm executor's tests (mostly waiting on a real
# Slurm: a task's smallest time limit is a minute), and all the others; each must pass.
# MAKEFLAGS is not passed on: the tests' own make commands run without this make's jobs.
SLURM_TESTS := tests/executors/test_slurm.py
# The Slurm tests wait, they hardly compute: pytest-xdist runs them side by side, each worker
# with a cluster of its own (tests/slurm_cluster.py picks free ports). With fewer tests than
# twice the workers xdist deals them out one by one, round-robin in the file's order, so that
# the four that wait up to a minute or more (the first four) start together.
SLURM_XDIST := -n 5
# The others compute: three workers share the two cores with the C tests, a module at a time
# (a module's fixtures, such as the README's copy of the repository or the scratch history's
# builds, are made once), the longest modules first (tests/conftest.py), so that no worker is
# left with a long module at the end (--no-loadscope-reorder: that order, not by test count).
PYTHON_XDIST := -n 3 --dist loadscope --no-loadscope-reorder
# The slowest tests are listed at the end of each run: where the time goes.
PYTEST := $(PYTHON) -m pytest -q --durations=12

# The fuzz tests (tests/hostile) run the ASan builds.
test-python: $(TEST_READY) all asan
	@unset MAKEFLAGS MFLAGS MAKELEVEL; mkdir -p build; \
	$(PYTEST) $(SLURM_XDIST) $(SLURM_TESTS) >build/pytest-slurm.log 2>&1 & slurm=$$!; \
	$(PYTEST) $(PYTHON_XDIST) --ignore=$(SLURM_TESTS); others=$$?; \
	wait $$slurm; slurm=$$?; echo "== $(SLURM_TESTS)"; cat build/pytest-slurm.log; \
	[ $$others = 0 ] && [ $$slurm = 0 ]

# ruff, and the harness's layering (pyproject.toml's import-linter contracts).
lint: $(TEST_READY)
	$(PYTHON) -m ruff check harness tests bench scripts examples
	.venv/bin/lint-imports

# Everything, three jobs at a time whatever -j make was given: pytest (whose Slurm half mostly
# waits) starts first, once build/ has the variants, and the C tests' builds and groups fill
# the other two; each job's output is printed whole when it ends. The tests' tools are set up
# first, so that the make that runs them reads this file with them installed (Open MPI's mpicc
# decides whether the mpi variant is built, and the scene scripts list what was built).
test: $(TEST_READY)
	@$(MAKE) --no-print-directory -j3 -Otarget test-python lint test-c

# ---- environment ----
$(PYTHON): requirements.txt pyproject.toml
	scripts/setup.sh

setup:
	scripts/setup.sh

$(TEST_READY): requirements.txt requirements-test.txt pyproject.toml scripts/setup.sh
	scripts/setup.sh --test

setup-test:
	scripts/setup.sh --test

# RUN_FLAGS: more options for the quick start's and the benchmarks' run (e.g.
# RUN_FLAGS=--dry-run).
RUN_FLAGS ?=
quickstart: setup
	$(MAKE) all
	$(PYTHON) harness/run.py configs/quickstart.yaml $(RUN_FLAGS)

# A user's runs write only results/ and report/, which git ignores; the project's own
# measurements are published/, refreshed only by these.
PUBLISHED := published/results
PUBLISHED_NAMES := $(notdir $(patsubst %/cells,%,$(wildcard $(PUBLISHED)/*/cells)))
PUBLISH_CONFIGS ?= $(foreach n,$(PUBLISHED_NAMES),$(firstword $(wildcard configs/$(n).yaml examples/$(n)/$(n).yaml)))
publish: all $(PYTHON)
	$(PYTHON) harness/run.py --results-dir $(PUBLISHED) $(PUBLISH_CONFIGS) $(RUN_FLAGS)

publish-report: $(PYTHON)
	$(PYTHON) -m harness report --results-dir $(PUBLISHED)

FUZZ_SECONDS ?= 600
fuzz: $(TEST_READY) all asan
	$(PYTHON) -m tests.hostile.fuzz --seconds $(FUZZ_SECONDS)

BENCH_CONFIGS ?= configs/bench-core.yaml configs/bench-grid.yaml configs/relative.yaml
# build/grid-f32: configs/bench-grading.yaml's float program
bench: all build/grid-f32 $(PYTHON)
	$(PYTHON) harness/run.py $(BENCH_CONFIGS) $(RUN_FLAGS)

clean:
	rm -rf build
