"""A machine's session spreads kept by noise level beside its description, and the one a
session of a given noise finds."""

from __future__ import annotations

import json
import math
from pathlib import Path

from harness import stats
from harness.store import records, sessions
from harness.store.layout import ResultsRoot

from tests.records import kept_spreads


def find_session(roots: list[Path], machine_id: str, noise: float = math.nan
                 ) -> stats.SessionSpread:
    """The spread a run of this noise takes from the levels kept under the roots."""
    return stats.spread_at(kept_spreads(roots, machine_id), noise)


def entry(absolute: float, noise: float | None, date: str) -> dict[str, object]:
    found: dict[str, object] = {"absolute": absolute, "ratio": absolute / 10, "date": date,
                                "config": "c.yaml", "reruns": 5}
    return found if noise is None else {**found, "noise": noise}


def test_levels_are_kept_by_noise_and_a_session_takes_the_spread_at_its_own(tmp_path: Path) -> None:
    path = sessions.keep_session(tmp_path, "m1", {"cpu_model": "x"}, entry(0.05, 0.02, "1"),
                                 stats.supersedes)
    sessions.keep_session(tmp_path, "m1", {}, entry(0.25, 0.22, "2"), stats.supersedes)
    # a newer quiet one replaces the quiet level, not the noisy one
    sessions.keep_session(tmp_path, "m1", {}, entry(0.04, 0.03, "3"), stats.supersedes)
    data = records.read_json(path)
    assert isinstance(data, dict) and data["cpu_model"] == "x"
    assert [e["absolute"] for e in data[sessions.LEVELS_KEY]] == [0.25, 0.04]
    assert data[sessions.SESSION_KEY]["absolute"] == 0.04  # the newest, as compare reads it
    assert find_session([tmp_path], "m1", 0.01).absolute == 0.04
    assert find_session([tmp_path], "m1", 0.3).absolute == 0.25
    between = find_session([tmp_path], "m1", 0.125)
    assert 0.04 < between.absolute < 0.25 and between.noise == 0.125
    assert find_session([tmp_path], "m1").absolute == 0.04  # noise unknown: newest
    assert find_session([tmp_path], "other", 0.1).source.startswith("default")


def test_a_file_kept_before_levels_is_one_level_of_unknown_noise(tmp_path: Path) -> None:
    path = ResultsRoot(tmp_path).calibration("m1")
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({sessions.SESSION_KEY: entry(0.06, None, "1")}))
    assert find_session([tmp_path], "m1", 0.3).absolute == 0.06
    assert math.isnan(find_session([tmp_path], "m1", 0.3).noise)
    # the next one kept supersedes it (its noise unknown)
    sessions.keep_session(tmp_path, "m1", {}, entry(0.25, 0.22, "2"), stats.supersedes)
    assert [e["absolute"] for e in records.read_json(path)[sessions.LEVELS_KEY]] == [0.25]
    # one of unknown noise kept later leaves the known levels be: it serves a session whose
    # noise is unknown
    sessions.keep_session(tmp_path, "m1", {}, entry(0.09, None, "3"), stats.supersedes)
    assert [e["absolute"] for e in records.read_json(path)[sessions.LEVELS_KEY]] == [0.25, 0.09]
    assert find_session([tmp_path], "m1", 0.3).absolute == 0.25
    assert find_session([tmp_path], "m1").absolute == 0.09


def test_an_entry_written_last_by_a_harness_without_levels_counts(tmp_path: Path) -> None:
    path = sessions.keep_session(tmp_path, "m1", {}, entry(0.05, 0.02, "1"),
                                 stats.supersedes)
    data = records.read_json(path)
    path.write_text(json.dumps({**data, sessions.SESSION_KEY: entry(0.3, None, "2")}))
    assert find_session([tmp_path], "m1").absolute == 0.3  # the newest, noise unknown
    assert find_session([tmp_path], "m1", 0.02).absolute == 0.05


def test_the_newest_of_two_roots_keeps_a_level(tmp_path: Path) -> None:
    here, repo = tmp_path / "here", tmp_path / "repo"
    sessions.keep_session(repo, "m1", {}, entry(0.05, 0.02, "1"), stats.supersedes)
    sessions.keep_session(repo, "m1", {}, entry(0.30, 0.25, "1"), stats.supersedes)
    sessions.keep_session(here, "m1", {}, entry(0.07, 0.03, "2"), stats.supersedes)
    assert find_session([here, repo], "m1", 0.0).absolute == 0.07
    assert find_session([here, repo], "m1", 0.4).absolute == 0.30
