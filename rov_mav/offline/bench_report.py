"""The bench's Markdown: one table per mission (controller x scenario group), then who leads where, and with several
tunes how each tune did."""

from __future__ import annotations

import math
from collections.abc import Sequence

from rov_mav.offline.bench import (ALL_GROUPS, BenchResult, Interval, RunFigures, Summary, mean_interval,
                                   paired_difference)

# (figure, column title, scale to the shown unit)
COLUMNS = (("rms_position_m", "RMS position error (cm)", 100.0),
           ("max_position_m", "max position error (cm)", 100.0),
           ("rms_attitude_rad", "RMS attitude error (deg)", math.degrees(1.0)),
           ("energy_wh", "energy (Wh)", 1.0),
           ("saturation_fraction", "saturated (% of time)", 100.0))


LEADERS_TITLE = "Who tracks best where"


def _cell(interval: Interval, scale: float) -> str:
    if math.isnan(interval.mean):
        return "-"
    return f"{interval.mean * scale:.3g} [{interval.low * scale:.3g}, {interval.high * scale:.3g}]"


def groups(summaries: Sequence[Summary], mission: str) -> list[str]:
    """The mission's scenario groups in file order, then ALL_GROUPS."""
    seen = [s.group for s in summaries if s.mission == mission and s.group != ALL_GROUPS]
    return list(dict.fromkeys(seen)) + [ALL_GROUPS]


def leader(summaries: Sequence[Summary], runs: Sequence[RunFigures], mission: str, group: str,
           figure: str = "rms_position_m") -> tuple[Summary, bool] | None:
    """Who leads a group: fewest failures first, then the lowest mean `figure`; and whether the lead is clear: every
    other controller failed more often, or as often with the leader's paired difference (`paired_difference`, same
    scenarios and seeds) wholly below zero. None when every run of every controller failed."""
    rows = [s for s in summaries if s.mission == mission and s.group == group and s.failures < s.runs]
    if not rows:
        return None
    rows.sort(key=lambda s: (s.failures, s.figures[figure].mean))
    best = rows[0]
    clear = all(other.failures > best.failures
                or paired_difference(runs, best.controller, other.controller, mission, group, figure).high < 0
                for other in rows[1:])
    return best, clear


def tune_rows(runs: Sequence[RunFigures], mission: str, controllers: Sequence[str]) -> list[str]:
    """Per controller, each tune's mean RMS position error over all groups (cm) and its failures."""
    rows = []
    for controller in controllers:
        cells = []
        for tune in sorted({r.tune for r in runs if r.mission == mission and r.controller == controller}):
            own = [r for r in runs if r.mission == mission and r.controller == controller and r.tune == tune]
            done = [r.rms_position_m for r in own if r.completed]
            mean = mean_interval(done).mean * 100.0
            cells.append(("-" if math.isnan(mean) else f"{mean:.3g}") + f" ({len(own) - len(done)}/{len(own)})")
        rows.append(f"| {mission} | {controller} | " + " | ".join(cells) + " |")
    return rows


def markdown(result: BenchResult, settings: dict) -> str:
    """bench.md: how it was run, a table per mission, the leader per scenario group, and each tune's result."""
    s = settings
    seeds = s["swarm_seeds"]
    tuned = (f"swarm seed {seeds[0]}" if len(seeds) == 1 else
             f"{len(seeds)} independent tunes, swarm seeds {seeds[0]}-{seeds[-1]}")
    cells = ("mean over the completed runs" if len(seeds) == 1 else
             "mean of the tunes' means over their completed runs")
    lines = [
        "# rov-mav bench",
        "",
        f"Controllers {', '.join(s['controllers'])}; each PSO-tuned ({s['particles']} particles x {s['iterations']} "
        f"iterations, {tuned}, tracking cost, mean over the training scenarios of `{s['training']}`) per mission, "
        f"then flown on the held-out scenarios of `{s['held_out']}` with {s['seeds']} noise seeds each. Cells: "
        f"{cells} [{s['interval']}]; failures: runs that diverged. Energy: electrical, T200 data at "
        f"{s['voltage_v']:g} V. Wall time {result.timing['total_s']:.0f} s (tuning {result.timing['tune_s']:.0f} s, "
        f"held-out runs {result.timing['evaluate_s']:.0f} s) with {s['compute']}.",
    ]
    missions = list(dict.fromkeys(x.mission for x in result.summaries))
    for mission in missions:
        lines += ["", f"## {mission}", "",
                  "| controller | group | runs | failures | " + " | ".join(c[1] for c in COLUMNS) + " |",
                  "|---|---|---:|---:|" + "---:|" * len(COLUMNS)]
        for group in groups(result.summaries, mission):
            for row in (x for x in result.summaries if x.mission == mission and x.group == group):
                cells = [_cell(row.figures[f], scale) for f, _, scale in COLUMNS]
                lines.append(f"| {row.controller} | {group} | {row.runs} | {row.failures} | " + " | ".join(cells)
                             + " |")
    lines += ["", f"## {LEADERS_TITLE}", "",
              "Fewest failures first, then the lowest mean RMS position error; *clear*: every other controller failed "
              "more often, or the 95 % t-interval of the paired difference (leader minus it, over the scenarios and "
              "seeds both completed" + ("" if len(seeds) == 1 else "; over the tunes' mean differences, tune i "
                                        "against tune i") + ") lies wholly below zero.",
              "", "| mission | group | controller | failures | RMS position error (cm) | lead |",
              "|---|---|---|---:|---:|---|"]
    for mission in missions:
        for group in groups(result.summaries, mission):
            lead = leader(result.summaries, result.runs, mission, group)
            if lead is None:
                lines.append(f"| {mission} | {group} | (every run diverged) | | | |")
                continue
            best, clear = lead
            lines.append(f"| {mission} | {group} | {best.controller} | {best.failures}/{best.runs} | "
                         f"{_cell(best.figures['rms_position_m'], 100.0)} | {'clear' if clear else 'overlapping'} |")
    if len(seeds) > 1:
        lines += ["", "## Each tune", "",
                  "Mean RMS position error (cm) over all groups of each tune's completed runs, (failures/runs): how "
                  "much where the swarm landed decides.", "",
                  "| mission | controller | " + " | ".join(f"seed {seed}" for seed in seeds) + " |",
                  "|---|---|" + "---:|" * len(seeds)]
        for mission in missions:
            lines += tune_rows(result.runs, mission, s["controllers"])
    return "\n".join(lines) + "\n"
