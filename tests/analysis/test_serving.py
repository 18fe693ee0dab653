"""A serial variant's one cell, shown at every thread count its scene's other cells ran at:
the same measurement at each (so seq's line is flat and every speedup is over it), marked,
counted once; left as it is where nothing else ran, and beside rows measured before it was
measured once."""

from __future__ import annotations

import pandas as pd
from harness.analysis import speedup
from harness.analysis.serving import ONE_THREAD_RUN, measured_once, serving
from harness.spec.facts import Variants


def frame(*cells: tuple[str, int, float], n: int = 100) -> pd.DataFrame:
    """Cells (variant, threads, median seconds) of one scene on one machine."""
    return pd.DataFrame([{
        "machine": "m", "variant": variant, "build": "f64", "scene": "random", "n": float(n),
        "L": 100.0, "r": 1.0, "steps": 1.0, "mode": "perf", "seed": 1.0, "schedule": "",
        "threads": float(threads), "status": "ok", "wall_median_s": median,
        "wall_times_s": (median, median), "oversubscribed": False, "runs": 2.0,
        "wall_min_s": median, "wall_stddev_s": 0.0, "identical": True,
        "cell_id": f"{variant}{threads}{n}"} for variant, threads, median in cells])


def shown(df: pd.DataFrame) -> list[tuple[str, int, float, bool]]:
    return [(r.variant, int(r.threads), r.wall_median_s, bool(r.one_thread_run))
            for r in df.itertuples()]


def test_seq_is_shown_at_each_count_the_others_ran_at_from_one_measurement(facts: Variants) -> None:
    df = serving(frame(("seq", 1, 4.0), ("p1d", 1, 4.4), ("p1d", 2, 2.2), ("p1d", 3, 1.6)), facts)
    assert sorted(shown(df)) == sorted([
        ("seq", 1, 4.0, True), ("seq", 2, 4.0, True), ("seq", 3, 4.0, True),
        ("p1d", 1, 4.4, False), ("p1d", 2, 2.2, False), ("p1d", 3, 1.6, False)])
    assert set(df.loc[df["variant"] == "seq", "cell_id"]) == {"seq1100"}
    assert len(measured_once(df)) == 4
    table = speedup.with_speedup(df, facts).set_index(["variant", "threads"])
    # every speedup is over the same measurement; seq's own is 1 at each count, and it is
    # charged no efficiency for threads it never ran
    assert table.loc[("p1d", 2), "speedup"] == 4.0 / 2.2
    assert list(table.loc["seq", "speedup"]) == [1.0, 1.0, 1.0]
    assert table.loc[("seq", 3), "efficiency"] != table.loc[("seq", 3), "efficiency"]  # NaN


def test_where_the_others_ran_at_one_count_seq_is_shown_there(facts: Variants) -> None:
    """The quick start: every variant at 2 threads, seq run with 1."""
    df = serving(frame(("seq", 1, 4.0), ("p1d", 2, 2.2)), facts)
    assert shown(df) == [("seq", 2, 4.0, True), ("p1d", 2, 2.2, False)]
    table = speedup.cell_table(df, ["variant"], facts)
    assert list(table[ONE_THREAD_RUN]) == [True, False]  # the table says it ran with one


def test_each_scene_serves_its_own_counts(facts: Variants) -> None:
    df = serving(pd.concat([frame(("seq", 1, 1.0), ("p1d", 2, 0.6)),
                            frame(("seq", 1, 9.0), ("p1d", 4, 3.0), n=300)]), facts)
    assert sorted((int(r.n), r.variant, int(r.threads)) for r in df.itertuples()) == [
        (100, "p1d", 2), (100, "seq", 2), (300, "p1d", 4), (300, "seq", 4)]


def test_alone_or_beside_older_rows_it_stays_as_it_is(facts: Variants) -> None:
    alone = frame(("seq", 1, 4.0))
    assert shown(serving(alone, facts)) == [("seq", 1, 4.0, True)]
    older = frame(("seq", 1, 4.0), ("seq", 2, 4.1), ("p1d", 1, 4.4), ("p1d", 2, 2.2))
    assert sorted(shown(serving(older, facts))) == sorted([
        ("seq", 1, 4.0, True), ("seq", 2, 4.1, True),
        ("p1d", 1, 4.4, False), ("p1d", 2, 2.2, False)])
    parallel = frame(("p1d", 1, 4.4), ("p1d", 2, 2.2))
    assert serving(parallel, facts) is parallel and ONE_THREAD_RUN not in parallel.columns
