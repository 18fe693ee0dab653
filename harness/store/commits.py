"""The commits of a history (`history`): <experiment>/history.json, the latest range measured,
oldest first, each with its subject and whether it changed what the binaries are made of."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from harness.store import atomic
from harness.store.layout import ExperimentDir


@dataclass(frozen=True)
class CommitInfo:
    sha: str
    subject: str
    touches_code: bool  # changed variants/ or the Makefile

    @property
    def short(self) -> str:
        return self.sha[:10]


def save_commits(exp: ExperimentDir, commits: Sequence[CommitInfo]) -> None:
    atomic.atomic_write_json(exp.history_commits, [
        {"commit": c.sha, "subject": c.subject, "touches_code": c.touches_code}
        for c in commits])
