"""The ranks axis end to end with real Open MPI and hyperfine: an MPI variant's cells run under
mpirun at each ranks x threads and agree with seq byte for byte, the record carries where the
ranks ran and what they spent in MPI, the report shows ranks against threads; a variant that is
not MPI is measured once whatever the ranks; a program names {ranks} and runs its own mpirun;
a rank that dies fails its cell with the reason; and the configs a machine cannot run (no
mpirun, more ranks than cores) are refused in one line."""

from __future__ import annotations

import csv
import os
import shutil
from pathlib import Path

import pytest
from harness import repo
from harness.analysis import results
from harness.analysis.ranks import cores_table
from harness.cli import main
from harness.errors import HarnessError
from harness.plan.cells import plan_cells
from harness.programs.section import class_table
from harness.spec.parse import load_config
from harness.spec.variants import VariantRegistry
from harness.store.layout import ExperimentDir

from commands import run_main

SCENE = "scene: {n: 300, L: 1500, r: 1, steps: 8, seed: 5}\n"
MEASURE = "measure: {warmup: 0, runs: 2, timeout_s: 60}\n"
# Open MPI's transports within one machine, as the C tests use (the harness chooses the
# messaging layer itself where the environment does not).
FAST_MPI = {"OMPI_MCA_btl": "self,vader"}


@pytest.fixture
def mpi_binaries(build_binaries, monkeypatch: pytest.MonkeyPatch) -> Path:
    if shutil.which("mpirun") is None:
        if os.environ.get("CI"):
            pytest.fail("mpirun is not installed (scripts/setup.sh --test installs Open MPI)")
        pytest.skip("mpirun is not installed")
    for name, value in FAST_MPI.items():
        monkeypatch.setenv(name, value)
    return build_binaries("seq", "grid", "mpi")


def rows_of(root: Path, name: str) -> list[dict[str, str]]:
    with (root / name / "results.csv").open() as handle:
        return list(csv.DictReader(handle))


def test_ranks_must_be_positive_whole_numbers(write_config) -> None:
    for bad in ("[0]", "[1, -2]", "[1.5]", "[]", "two"):
        path = write_config(f"name: r\nvariants: [mpi]\n{SCENE}ranks: {bad}\n")
        with pytest.raises(HarnessError) as caught:
            load_config(path)
        assert str(path) in str(caught.value) and "'ranks'" in str(caught.value)
        assert "\n" not in str(caught.value)


def test_only_mpi_variants_get_a_cell_per_ranks(write_config) -> None:
    plan = plan_cells(load_config(write_config(
        f"name: r\nvariants: [seq, grid, mpi]\n{SCENE}threads: [1, 2]\nranks: [1, 2, 4]\n")))
    cells = sorted((c.variant, c.threads, c.ranks if c.uses_ranks else None)
                   for c in plan.cells)
    assert cells == [("grid", 1, None), ("grid", 2, None),
                     ("mpi", 1, 1), ("mpi", 1, 2), ("mpi", 1, 4),
                     ("mpi", 2, 1), ("mpi", 2, 2), ("mpi", 2, 4),
                     ("seq", 1, None)]


def test_mpi_cells_agree_with_seq_and_record_their_ranks(
        mpi_binaries: Path, write_config, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    config = write_config(f"name: ranked\nvariants: [seq, grid, mpi]\n{SCENE}threads: [1, 2]\n"
                          f"ranks: [1, 2]\n{MEASURE}validate: true\n")
    root = tmp_path / "results"
    assert run_main([str(config), "--results-dir", str(root)]) == 0
    log = capsys.readouterr().err
    assert "ranked: 7 cells (7 measured, 0 cached): 7 ok" in log
    rows = rows_of(root, "ranked")
    assert all(r["status"] == "ok" and r["identical"] == "True" for r in rows)
    mpi_rows = {(int(r["threads"]), int(r["ranks"])): r for r in rows if r["variant"] == "mpi"}
    assert sorted(mpi_rows) == [(1, 1), (1, 2), (2, 1), (2, 2)]
    assert {r["ranks"] for r in rows if r["variant"] != "mpi"} == {""}
    experiment = results.load_experiment(ExperimentDir(root / "ranked"))
    for record in (listed.result for listed in experiment.listed):
        assert record.subject is not None and record.provenance is not None
        if record.subject.variant != "mpi":
            assert record.mpi is None
            continue
        ranks = record.subject.ranks
        assert record.provenance.command is not None
        assert record.provenance.command.startswith(f"{shutil.which('mpirun')} -np {ranks} ")
        assert record.mpi is not None
        assert (record.provenance.omp_env or {}).get("OMPI_MCA_pml") == "ob1"
        assert record.mpi.ranks_binding in {"core", "none"}
        assert record.mpi.ranks_oversubscribed == (
            ranks * (record.subject.threads or 1) > (os.cpu_count() or 1))
        # one rank exchanges nothing; two spend time and bytes in their exchanges
        assert record.mpi.mpi_s is not None and record.mpi.mpi_bytes_step is not None
        assert (record.mpi.mpi_bytes_step > 0) == (ranks > 1)
        assert record.mpi.rss_mib_max is not None and record.mpi.rss_mib_sum is not None
        assert record.mpi.rss_mib_max <= record.mpi.rss_mib_sum <= (
            record.mpi.rss_mib_max * ranks + 0.1)  # MiB to a tenth
    page = "".join(p.read_text() for p in (root / "report").rglob("*.html"))
    assert "MPI ranks" in page and "Speedup over ranks" in page
    assert "Every cell on the same number of cores" in page
    cores = cores_table(experiment.frame)
    assert sorted(zip(cores["cores"], cores["variant"], strict=True)) == [
        (1, "grid"), (1, "mpi"), (1, "seq"), (2, "grid"), (2, "mpi"), (2, "mpi")]
    assert cores.groupby("cores")["fastest"].sum().tolist() == [1, 1]
    # a second run measures nothing
    assert run_main([str(config), "--results-dir", str(root), "--no-report"]) == 0
    assert "ranked: 7 cells (0 measured, 7 cached): 7 ok" in capsys.readouterr().err


def test_a_program_names_its_ranks_and_a_dying_rank_fails_its_cell(
        mpi_binaries: Path, write_config, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    mpi = mpi_binaries / "mpi"
    # rank 1 kills itself before the run; rank 0 then waits on it until mpirun ends the job
    dying = (f"mpirun -np {{ranks}} sh -c '[ \\\"$OMPI_COMM_WORLD_RANK\\\" = 1 ] && kill -9 $$; "
             f"exec {mpi} --threads {{threads}} {{input}}'")
    config = write_config(f"""\
name: progs
variants: [seq, theirs, dying]
programs:
  theirs: "mpirun -np {{ranks}} {mpi} --threads {{threads}} {{input}}"
  dying: "{dying}"
{SCENE}threads: [1]
ranks: [1, 2]
exclude: [{{variant: dying, ranks: 1}}]
{MEASURE}validate: true
""")
    root = tmp_path / "results"
    # a cell that fails is a result: the run goes on and ends well
    assert run_main([str(config), "--results-dir", str(root), "--no-report"]) == 0
    log = capsys.readouterr().err
    rows = {(r["variant"], r["ranks"]): r for r in rows_of(root, "progs")}
    assert sorted(rows) == [("dying", "2"), ("seq", ""), ("theirs", "1"), ("theirs", "2")]
    for ranks in ("1", "2"):
        assert rows[("theirs", ranks)]["status"] == "ok"
        assert rows[("theirs", ranks)]["agreement"] == "identical"
    died = rows[("dying", "2")]
    assert died["status"] in {"crashed", "failed"}
    # mpirun ends the job with the status of the rank killed by signal 9, and says why
    assert "(exit 137)" in died["note"] and "---" in died["note"]
    assert "progs: 4 cells (4 measured, 0 cached): 1 crashed, 3 ok" in log
    # graded per rank count: a row of the class table for each
    grades = class_table(results.load_experiment(ExperimentDir(root / "progs")).frame)
    theirs = grades[grades["program"] == "theirs"]
    assert sorted(theirs["ranks"]) == [1, 2] and set(theirs["verdict"]) == {"identical"}
    assert main(["report", "--results-dir", str(root), "--out", str(tmp_path / "page")]) == 0


def test_no_mpirun_is_one_line_with_how_to_install(
        write_config, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    # PATH as it is, less Open MPI's launchers
    bare = tmp_path / "bin"
    bare.mkdir()
    for directory in os.environ["PATH"].split(os.pathsep):
        if not Path(directory).is_dir():
            continue
        for entry in Path(directory).iterdir():
            if entry.name not in {"mpirun", "mpiexec", "orterun"} and not (
                    bare / entry.name).exists():
                (bare / entry.name).symlink_to(entry)
    monkeypatch.setenv("PATH", str(bare))
    config = write_config(f"name: r\nvariants: [seq, mpi]\n{SCENE}ranks: [2]\n")
    assert run_main([str(config), "--results-dir", str(tmp_path / "results")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:")
    assert "mpirun not found" in err[0] and "apt-get install openmpi-bin" in err[0]


def test_more_ranks_than_cores_needs_oversubscribe(
        mpi_binaries: Path, write_config, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    cores = os.cpu_count() or 1
    # a program starts its own mpirun: the config's consent reaches it too
    many = (f"name: many\nvariants: [seq, mpi, theirs]\n"
            f"programs: {{theirs: \"mpirun -np {{ranks}} {mpi_binaries / 'mpi'} {{input}}\"}}\n"
            f"{SCENE}ranks: [{cores + 1}]\n{MEASURE}validate: true\n")
    config = write_config(many)
    root = tmp_path / "results"
    assert run_main([str(config), "--results-dir", str(root), "--no-report"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'ranks'" in err[0] and "oversubscribe: true" in err[0]
    assert not (root / "many" / "results.csv").exists()
    config.write_text(many + "executor: {oversubscribe: true}\n")
    assert run_main([str(config), "--results-dir", str(root), "--no-report"]) == 0
    capsys.readouterr()
    rows = {r["variant"]: r for r in rows_of(root, "many")}
    assert rows["mpi"]["status"] == "ok" and rows["mpi"]["identical"] == "True"
    assert rows["theirs"]["status"] == "ok" and rows["theirs"]["agreement"] == "identical"
    listed = results.load_experiment(ExperimentDir(root / "many")).listed
    record = next(item.result for item in listed
                  if item.result.subject and item.result.subject.variant == "mpi")
    assert record.mpi is not None and record.mpi.ranks_oversubscribed
    assert record.provenance is not None and record.provenance.command is not None
    assert "--oversubscribe" in record.provenance.command.split()
    assert record.subject is not None and record.subject.ranks == cores + 1


def test_without_mpicc_the_mpi_variant_is_left_out_and_named(
        write_config, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("MPICC", "no-such-mpicc")  # the Makefile's compiler of MPI variants
    registry = VariantRegistry()
    assert "mpi" in registry.unbuilt and "mpi" not in registry.names and "seq" in registry.names
    path = write_config(f"name: r\nvariants: [seq, mpi]\n{SCENE}ranks: [2]\n")
    with pytest.raises(HarnessError) as caught:
        load_config(path, registry)
    assert str(caught.value) == (
        f"{path}: key 'variants': 'mpi' is an MPI variant, which make leaves out where mpicc "
        "is not found; install Open MPI: sudo apt-get install openmpi-bin libopenmpi-dev")
    # every other config plans and runs as before
    quickstart = repo.REPO_ROOT / "configs" / "quickstart.yaml"
    assert run_main([str(quickstart), "--dry-run"]) == 0
    assert "quickstart:" in capsys.readouterr().out
