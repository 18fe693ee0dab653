"""Where things live in the repository: the one home of its root and its top-level folders.

Standard library only: the launcher imports this before it knows whether the harness's
packages are installed.
"""

from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
BUILD_DIR = "build"  # make's binaries: build/NAME, build/NAME-BUILD
VARIANTS_DIR = "variants"  # variants/NAME.c, one file a variant
OMPCOST = "ompcost"  # build/ompcost (tools/ompcost.c): the OpenMP runtime's cost per operation
PEAKRSS = "peakrss"  # build/peakrss (tools/peakrss.c): a command's peak resident memory
# A user's measurements and their report: git ignores both, so measuring changes no tracked file.
DEFAULT_RESULTS_DIR = REPO_ROOT / "results"
DEFAULT_REPORT_DIR = REPO_ROOT / "report"
# The project's own measurements and their report, committed and refreshed by `make publish`.
PUBLISHED_DIR = REPO_ROOT / "published"
PUBLISHED_RESULTS_DIR = PUBLISHED_DIR / "results"
PUBLISHED_REPORT_DIR = PUBLISHED_DIR / "report"
VENV_PYTHON = REPO_ROOT / ".venv" / "bin" / "python"
REPORT_SUBDIR = "report"  # another results root's own report, inside it


def default_report_dir(results_dir: Path) -> Path:
    """Where a results root's report goes: the repository's report/ for its results/, the
    published report for the published results, else `report/` inside the results root (a
    run elsewhere never writes over either)."""
    resolved = results_dir.resolve()
    for results, report in ((DEFAULT_RESULTS_DIR, DEFAULT_REPORT_DIR),
                            (PUBLISHED_RESULTS_DIR, PUBLISHED_REPORT_DIR)):
        if resolved == results.resolve():
            return report
    return results_dir / REPORT_SUBDIR
