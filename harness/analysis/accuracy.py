"""Error against run time, and the accuracy and stability checks read back (the check columns
of results.csv): each cell's deviation from its baseline output, the Pareto front of time
against error per scene, which checks each cell passed, the scene x variant/build matrix, and
which variants and builds are trusted on which scenes, with why."""

import math
from collections.abc import Sequence

import numpy as np
import pandas as pd

from harness.analysis import cells
from harness.analysis.display import display_name, format_value
from harness.analysis.flags import validation_text
from harness.spec.facts import Variants
from harness.store.columns import OK


def pareto_mask(times: pd.Series, errors: pd.Series) -> pd.Series:
    """True for the cells no other cell beats on both time and error (lower is better)."""
    # By increasing time, a cell is on the front when it is more accurate than every faster
    # one (ties in time go to the more accurate cell, seen first).
    front = pd.DataFrame({"time": times, "error": errors}).sort_values(["time", "error"],
                                                                       kind="stable")
    faster = front["error"].cummin().shift(fill_value=math.inf)
    return (front["error"] < faster).reindex(times.index)


def pareto_by_scene(rows: pd.DataFrame, error: str) -> pd.Series:
    """Per row, whether it is on its scene's front of time against `error` (cells of different
    scenes are not comparable, so each scene has its own front); False where `error` is
    missing."""
    mask = pd.Series(False, index=rows.index)
    scenes = cells.present(rows, cells.SCENE_KEYS)
    for _, group in rows[rows[error].notna()].groupby(scenes, dropna=False):
        mask[group.index] = pareto_mask(group["wall_median_s"], group[error])
    return mask


def has_error_data(df: pd.DataFrame) -> bool:
    """Whether the rows carry a deviation worth plotting: several builds, or a nonzero error
    in an ok cell. An invalid cell's error is a defect, listed with the warnings, not a
    trade-off between speed and accuracy."""
    ok = df[(df["status"] == OK) & df["max_pos_err"].notna()]
    if ok.empty:
        return False
    return ok["build"].nunique() > 1 or bool((ok["max_pos_err"] > 0).any())


def error_table(df: pd.DataFrame, keys: Sequence[str], variants: Variants) -> pd.DataFrame:
    """Per timed cell with a measured error: time, errors and whether it is on the Pareto front
    (variants in the order of `variants`)."""
    rows = cells.timed_rows(df)
    rows = rows[rows["max_pos_err"].notna()]
    table = rows[[*keys, "wall_median_s", "max_pos_err", "max_vel_err", "count_mismatches"]
                 ].rename(columns={"wall_median_s": "median_s"})
    table["validation"] = rows.apply(validation_text, axis=1) if len(rows) else []
    table["pareto"] = pareto_by_scene(rows, "max_pos_err")
    return cells.sort_cells(table, keys, variants)


# Each check's column and what it tests, in the order the tables show them.
CHECKS: tuple[tuple[str, str, str], ...] = (
    ("finite", "chk_finite", "no NaN or Inf in any printed state"),
    ("in_box", "chk_in_box", "every centre in [r, L−r] (float builds: within a float ulp)"),
    ("energy", "chk_energy", "kinetic-energy drift within k·eps·(pair collisions)"),
    ("pcoll_even", "chk_pcoll_even", "sum of pcoll even"),
    ("threads", "chk_threads", "same output at the other thread counts"),
    ("exact", "chk_exact", "same output as seq of the same build (exact variants)"),
    ("shadow", "chk_shadow", "one step from each state: same collisions as __float128, error "
                             "within k·eps·(1+v/L)(1+v/r)"),
)
PASS_MARK = "✓"
FAIL_MARK = "✗"
# A one-step error below this fraction of a radius cannot flip more than about that fraction
# of the next step's contact decisions (a contact flips when it is within the error of
# grazing or of t = 1): the level at which a build's trajectory is trustworthy.
TRUST_ERR_R = 1e-6
MAX_LISTED = 8  # failing cells a check's row names


def has_check_data(df: pd.DataFrame) -> bool:
    """Whether the rows carry the accuracy and stability checks (`checks:` in the config)."""
    return "checks_passed" in df.columns and bool(df["checks_passed"].notna().any())


def scene_names(df: pd.DataFrame) -> pd.Series:
    """Per row, the name of its input: the scene label, plus the parameters that tell apart
    the inputs sharing that label (e.g. `random N=4000 L=12649.1 S=3`)."""
    keys = [k for k in cells.SCENE_KEYS if k not in (cells.MACHINE, "scene") and k in df.columns
            and df.groupby("scene", dropna=False)[k].nunique(dropna=False).max() > 1]
    if not keys:
        return df["scene"].astype(str)
    return df.apply(lambda row: " ".join([str(row["scene"])] + [
        f"{display_name(k)}={format_value(k, row[k])}" for k in keys]), axis=1)


def _checked(df: pd.DataFrame, variants: Variants) -> pd.DataFrame:
    rows = df[df["checks_passed"].notna()] if "checks_passed" in df.columns else df.iloc[0:0]
    names = scene_names(rows) if len(rows) else pd.Series([], dtype=object)
    rank = {name: i for i, name in enumerate(dict.fromkeys(names))}
    rows = rows.assign(scene_name=names, scene_rank=names.map(rank))
    return cells.sort_cells(rows, ["variant", "build"], variants)


def _failures(row: pd.Series) -> list[str]:
    failed = [name for name, column, _ in CHECKS
              if pd.notna(row.get(column)) and not bool(row[column])]
    text = row.get("checks_failed")
    if isinstance(text, str) and "run" in text.split():
        failed.insert(0, "run")
    return failed


def stability_matrix(df: pd.DataFrame, variants: Variants) -> pd.DataFrame:
    """Scene × variant/build: ✓ where every check passed, else ✗ and the failing checks."""
    rows = _checked(df, variants)
    rows = rows.assign(label=rows["variant"] + "/" + rows["build"])
    scenes = list(dict.fromkeys(rows.sort_values("scene_rank", kind="stable")["scene_name"]))
    marks = {}
    for key, group in rows.groupby(["scene_name", "label"], sort=False):
        failed = list(dict.fromkeys(f for _, r in group.iterrows() for f in _failures(r)))
        marks[key] = f"{FAIL_MARK} " + ", ".join(failed) if failed else PASS_MARK
    return pd.DataFrame({"scene": scenes, **{label: [marks.get((s, label), "") for s in scenes]
                                             for label in dict.fromkeys(rows["label"])}})


def check_summary(df: pd.DataFrame, variants: Variants) -> pd.DataFrame:
    """Per check: what it tests, cells checked, passed, failed and the failing cells."""
    rows = _checked(df, variants)
    out = []
    for name, column, what in CHECKS:
        if column not in rows.columns or rows[column].isna().all():
            continue
        known = rows[rows[column].notna()]
        failed = known[~known[column].astype(bool)]
        where = [f"{r['scene_name']}: {r['variant']}/{r['build']}" for _, r in failed.iterrows()]
        listed = ", ".join(where[:MAX_LISTED]) + (f", … {len(where) - MAX_LISTED} more"
                                                  if len(where) > MAX_LISTED else "")
        out.append({"check": name, "what": what, "checked": len(known),
                    "passed": len(known) - len(failed), "failed": len(failed), "where": listed})
    return pd.DataFrame(out, columns=["check", "what", "checked", "passed", "failed", "where"])


def accuracy_table(df: pd.DataFrame, keys: Sequence[str], variants: Variants) -> pd.DataFrame:
    """Per checked, timed cell: time, whole-run error against the baseline, the shadow-step
    error, collision-set differences, energy drift and steps until r apart from the truth;
    ✓ marks each scene's Pareto front of time against the mean shadow error."""
    rows = cells.timed_rows(_checked(df, variants))
    table = rows.reindex(columns=[
        *keys, "wall_median_s", "max_pos_err", "shadow_pos_err", "shadow_err_r",
        "shadow_set_diff", "energy_drift_max", "div_steps_to_r"]).rename(
        columns={"wall_median_s": "median_s"})
    table["pareto"] = pareto_by_scene(rows, "shadow_pos_err") \
        if "shadow_pos_err" in rows.columns else False
    return cells.sort_cells(table, keys, variants)


def _step_error(row: pd.Series) -> float:
    """The one-step error in radii (0 where not measured)."""
    value = row.get("shadow_err_r")
    return 0.0 if pd.isna(value) else float(value)


def _trusted(row: pd.Series) -> bool:
    """Every check passed and one step within TRUST_ERR_R radii of __float128's. (How soon
    the whole run is a radius off the truth is shown, not judged: in a dense scene chaos gets
    every precision there within a few steps.)"""
    return not _failures(row) and _step_error(row) <= TRUST_ERR_R


def _reason(row: pd.Series) -> str:
    """Why a cell is not trusted, with the measured numbers."""
    parts = []
    for failure in _failures(row):
        if failure == "shadow" and float(row.get("shadow_set_diff") or 0) > 0:
            parts.append(f"collisions differ from __float128 in "
                         f"{float(row['shadow_set_diff']):.0%} of steps")
        elif failure == "energy":
            parts.append(f"energy drift {float(row['energy_drift_max']):.1e}")
        else:
            parts.append(f"{failure} check fails")
    if (error := _step_error(row)) > TRUST_ERR_R:
        parts.append(f"one-step error {error:.1e} r")
    return f"{row['scene_name']} ({'; '.join(parts)})"


def trust_table(df: pd.DataFrame, variants: Variants) -> pd.DataFrame:
    """Per variant/build over the checked scenes: how many it is trusted on (every check
    passed, a one-step error below TRUST_ERR_R radii, and never a radius from the truth), its
    median and worst one-step error, and the scenes it is not trusted for, with why."""
    rows = _checked(df, variants)
    out = []
    for (variant, build), group in rows.groupby(["variant", "build"], sort=False):
        errors = group.get("shadow_err_r", pd.Series(dtype=float)).dropna()
        worst = ""
        if len(errors) and float(errors.max()) > 0:
            at = errors.idxmax()
            worst = f"{group.loc[at, 'scene_name']} ({float(errors[at]):.1e} r)"
        bad = group[~group.apply(_trusted, axis=1)]
        out.append({
            "label": f"{variant}/{build}", "scenes": group["scene_name"].nunique(),
            "trusted": group["scene_name"].nunique() - bad["scene_name"].nunique(),
            "typical_err_r": float(errors.median()) if len(errors) else np.nan,
            "worst": worst,
            "not_trusted": "; ".join(_reason(r) for _, r in bad.iterrows()) or "—",
        })
    columns = ["label", "scenes", "trusted", "typical_err_r", "worst", "not_trusted"]
    return pd.DataFrame(out, columns=columns)


def _short_reason(group: pd.DataFrame) -> str:
    """The gist of why a scene's cells are not trusted: the worst one-step error in radii,
    else differing collisions, else the failing checks."""
    errors = group.get("shadow_err_r", pd.Series(dtype=float)).dropna()
    if len(errors) and float(errors.max()) > TRUST_ERR_R:
        return f"{float(errors.max()):.1e} r per step"
    if "shadow_set_diff" in group and (group["shadow_set_diff"].fillna(0) > 0).any():
        return "collisions differ"
    return ", ".join(dict.fromkeys(f for _, r in group.iterrows() for f in _failures(r)))


def build_trust(df: pd.DataFrame, variants: Variants) -> pd.DataFrame:
    """Per build (precision or formula), over its variants that share the core's arithmetic
    (their facts among `variants`): how many scenes all of them are trusted on, and the others
    with why."""
    rows = _checked(df, variants)
    # a variant that is not exact computes contact times with arithmetic of its own
    rows = rows[~cells.variant_fact(rows["variant"], lambda f: not f.exact, variants)]
    out = []
    for build, group in rows.groupby("build", sort=False):
        scenes = list(dict.fromkeys(group["scene_name"]))
        bad = group[~group.apply(_trusted, axis=1)]
        failing = [f"{scene} ({_short_reason(cell_rows)})"
                   for scene, cell_rows in bad.groupby("scene_name", sort=False)]
        out.append({"build": build, "variants": ", ".join(dict.fromkeys(group["variant"])),
                    "scenes": len(scenes), "trusted": len(scenes) - bad["scene_name"].nunique(),
                    "not_trusted": ", ".join(failing)})
    table = pd.DataFrame(out, columns=["build", "variants", "scenes", "trusted", "not_trusted"])
    return table.sort_values("trusted", ascending=False, kind="stable").reset_index(drop=True)
