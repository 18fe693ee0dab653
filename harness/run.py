"""Run experiments: `python harness/run.py configs/threads.yaml [more.yaml] [options]`.

Works as a script and as `python -m harness.run`. Under a Python that lacks the harness's
packages it re-executes itself with the repository's .venv/bin/python.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from harness import runner

REPO_ROOT = Path(__file__).resolve().parent.parent
REQUIRED_MODULES = ("yaml", "numpy", "pandas", "matplotlib", "scipy", "psutil")
QUICK_REPORT = "report-quick"
EXIT_ERROR = 2
EXIT_INTERRUPTED = 130


def parse_args(argv: Sequence[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="harness/run.py", description="Measure the cells of experiment configs.")
    parser.add_argument("configs", nargs="+", type=Path, help="experiment YAML files")
    parser.add_argument("--dry-run", action="store_true",
                        help="list the cells and which are cached; measure nothing")
    parser.add_argument("--quick", action="store_true",
                        help="smoke run: n <= 400, steps <= 5, into results/<name>-quick/")
    parser.add_argument("--force", action="store_true", help="re-measure cached cells")
    parser.add_argument("--no-report", action="store_true", help="do not render the report")
    parser.add_argument("--results-dir", type=Path, default=REPO_ROOT / "results",
                        help="results root (default: <repo>/results)")
    parser.add_argument("--report-dir", type=Path, default=REPO_ROOT / "report",
                        help="where the report is rendered (default: <repo>/report; "
                        "--quick runs go to <report-dir>/report-quick)")
    parser.add_argument("--no-wait", action="store_true",
                        help="when another run is measuring on this machine, stop with an "
                        "error instead of waiting for it")
    parser.add_argument("--hyperfine", default="hyperfine", help="hyperfine executable")
    parser.add_argument("--executor", choices=("local", "slurm"), default=None,
                        help="where cells are measured: local (one after another here; the "
                        "default) or slurm (one job-array task per cell); overrides the "
                        "config's executor.kind")
    parser.add_argument("--collect", action="store_true",
                        help="slurm: wait for the cells already submitted (e.g. by a killed "
                        "run) and record them; submit nothing")
    parser.add_argument("--partition", default=None,
                        help="slurm: the partition (overrides the config's executor.partition)")
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    from harness import lock, runner
    from harness.config import load_config
    from harness.errors import HarnessError

    args = parse_args(sys.argv[1:] if argv is None else argv)
    signal.signal(signal.SIGTERM, _terminate)
    run_lock = lock.RunLock(" ".join(str(p) for p in args.configs), wait=not args.no_wait,
                            log=sys.stderr)
    options = runner.Options(repo_root=REPO_ROOT, results_root=args.results_dir.resolve(),
                             quick=args.quick, force=args.force, dry_run=args.dry_run,
                             hyperfine=args.hyperfine, executor=args.executor,
                             collect=args.collect, partition=args.partition,
                             run_lock=run_lock)
    try:
        configs = [load_config(path) for path in args.configs]
        with run_lock:
            summaries = [runner.run_experiment(c, options, sys.stderr, sys.stdout)
                         for c in configs]
        if not (args.dry_run or args.no_report):
            render_report(options, args.report_dir, [s.directory.name for s in summaries])
    except HarnessError as exc:
        sys.stderr.write(f"error: {exc}\n")
        return EXIT_ERROR
    except BrokenPipeError:  # e.g. `--dry-run | head`
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - silence the flush at exit
        return 0
    except KeyboardInterrupt:
        sys.stderr.write("interrupted: finished cells are saved; run again to resume\n")
        return EXIT_INTERRUPTED
    return 0


def _terminate(signum: int, frame: object) -> None:
    """SIGTERM ends a run as Ctrl-C does: the running cell's processes are killed."""
    raise KeyboardInterrupt


def render_report(options: runner.Options, report_dir: Path, names: Sequence[str]) -> None:
    """Render the report with harness.report, when that module exists.

    A full run renders every experiment under the results root into `report_dir`; a --quick
    run renders only the quick experiments it just ran, into `report_dir/report-quick`.
    """
    try:
        from harness import report
    except ModuleNotFoundError as exc:
        if exc.name != "harness.report":
            raise
        sys.stderr.write("note: harness/report.py is not there yet; no report rendered\n")
        return
    if options.quick:
        path = report.render(options.results_root, report_dir / QUICK_REPORT, include_quick=True,
                             experiments=list(names))
    else:
        path = report.render(options.results_root, report_dir)
    sys.stderr.write(f"report: {path}\n")


if __name__ == "__main__":
    if not __package__:
        sys.path.insert(0, str(REPO_ROOT))
    from harness.reexec import ensure_packages

    ensure_packages(REQUIRED_MODULES, [str(Path(__file__).resolve())])
    sys.exit(main())
