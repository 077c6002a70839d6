"""The safety mark of a group of sweep rows, for the experiment tables (standard library only).

Every table of `scripts/` names a group of runs by this mark, so that no efficiency figure of
an unsafe run is printed without saying so: a run is unsafe when its `safe` column is false
(collisions, overlaps, teleports or emergency braking, see the guide's metrics page).
"""


def mark(rows):
    """'' when every run of `rows` was safe; ' ⚠ UNSAFE k/n' when k of them were not;
    ' (safety not recorded)' when the table has no `safe` column or a run lacks it."""
    values = [r.get("safe") for r in rows]
    unsafe = sum(1 for v in values if v == "false")
    if unsafe:
        return f" ⚠ UNSAFE {unsafe}/{len(rows)}"
    if any(v not in ("true", "false") for v in values):
        return " (safety not recorded)"
    return ""
