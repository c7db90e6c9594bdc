"""``impactcli sensitivity``: the paper's Table II reproduced on the simulator, with a
false-alarm soak and the detectors compared at matched (zero) false-alarm rates.

The study (:mod:`impactcli.study`): per arm, one simulated robot; a rigid model and
thresholds calibrated (leave-one-out) on collision-free, payload-free runs; a soak of
collision-free runs (task triangles, two-joint triangles, trapezoids, multi-sines, with the
variant's unknown payload) for false alarms per hour; impact cases on elastomers of each
stiffness at every trajectory amplitude. Deterministic for ``--seed``.

Output: Table II per variant at the calibrated thresholds and at each detector's
zero-false-alarm scale on the soak, a detection-vs-false-alarm table and a verdict per
variant; ``--json PATH`` (or ``-`` for stdout) writes schemas/sensitivity.schema.json;
``--markdown PATH`` writes the README's tables. Exit 0; 2 bad options; 3 bad study values;
70 an internal error (a bug).
"""

from __future__ import annotations

import json
import shlex
import sys
import time
from pathlib import Path
from typing import Any

import click

from .options import handle_errors


def _floats(ctx: click.Context, param: click.Parameter,
            value: str | None) -> tuple[float, ...] | None:
    if value is None:
        return None
    try:
        out = tuple(float(x) for x in value.split(",") if x.strip())
    except ValueError:
        raise click.BadParameter(f"expected comma-separated numbers, got {value!r}") from None
    if not out or any(not (x > 0) for x in out):
        raise click.BadParameter(f"expected positive numbers, got {value!r}")
    return out


def task_runner(jobs: int | None) -> Any:
    """Map tasks over a process pool (impactcli.run.executors) with a progress bar on stderr."""
    from tqdm import tqdm

    def run(fn: Any, items: list[Any], desc: str) -> list[Any]:
        out: list[Any] = [None] * len(items)
        if jobs is None or jobs <= 1:
            for i, x in enumerate(tqdm(items, desc=desc, file=sys.stderr, leave=False,
                                       disable=len(items) < 2)):
                out[i] = fn(x)
            return out
        from ..run.executors import TaskFailure, run_tasks

        with tqdm(total=len(items), desc=desc, file=sys.stderr, leave=False) as bar:
            for i, res in run_tasks(fn, items, jobs=jobs):
                if isinstance(res, TaskFailure):
                    raise RuntimeError(f"sensitivity task {i} failed: {res.reason}\n"
                                       f"{res.traceback}")
                out[i] = res
                bar.update(1)
        return out

    return run


@click.command("sensitivity")
@click.option("--arm", "arms", multiple=True,
              type=click.Choice(["assist_like", "assist_like+payload", "heavy_geared",
                                 "heavy_geared+payload"]),
              help="Robot variant(s) to study (repeatable) [default: all four; --quick: "
                   "assist_like].")
@click.option("--stiffness", callback=_floats, default=None,
              help="Elastomer stiffnesses [N/mm], comma-separated [default: 10.12,5.93,2.12].")
@click.option("--forces", callback=_floats, default=None,
              help="Nominal pressing forces [N] that set the trajectory amplitudes "
                   "[default: 1,1.5,2,3,4,6,8,12,16,24,32].")
@click.option("--case-seeds", type=click.IntRange(min=1), default=None,
              help="Cases (seeds) per stiffness and amplitude [default: 2].")
@click.option("--soak-minutes", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Length of each soak run [min]; 4 families → 4 × this per variant "
                   "[default: 15].")
@click.option("--soak-runs", type=click.IntRange(min=1), default=None,
              help="Soak runs per family [default: 1].")
@click.option("--seed", type=int, default=0, show_default=True, help="The study's seed.")
@click.option("--quick", is_flag=True,
              help="A small study for tests and CI (one arm, 3 amplitudes, 1-min soak runs).")
@click.option("--jobs", "-j", type=click.IntRange(min=1), default=None,
              help="Worker processes [default: serial].")
@click.option("--json", "json_out", default=None, metavar="PATH",
              help="Write the results as JSON (schemas/sensitivity.schema.json); '-' = stdout.")
@click.option("--markdown", "md_out", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Write the README's markdown tables to PATH.")
@handle_errors
def sensitivity_cmd(arms: tuple[str, ...], stiffness: tuple[float, ...] | None,
                    forces: tuple[float, ...] | None, case_seeds: int | None,
                    soak_minutes: float | None, soak_runs: int | None, seed: int, quick: bool,
                    jobs: int | None, json_out: str | None, md_out: Path | None) -> None:
    """Reproduce the paper's Table II on the simulator; soak for false alarms; compare the
    detectors at matched false-alarm rates."""
    from impactcli.study.runner import run_study
    from impactcli.study.spec import StudySpec
    from impactcli.study.tables import format_markdown, format_text

    from ..files import atomic_write_text, prepare_output

    for out in (md_out, None if json_out in (None, "-") else Path(json_out)):
        if out is not None:  # a bad output path stops the study before it runs
            prepare_output(out)
    changes: dict[str, Any] = {"seed": seed}
    if arms:
        changes["variants"] = tuple(dict.fromkeys(arms))
    if stiffness is not None:
        changes["stiffnesses"] = stiffness
    if forces is not None:
        changes["forces_n"] = forces
    if case_seeds is not None:
        changes["case_seeds"] = case_seeds
    if soak_minutes is not None:
        changes["soak_run_s"] = soak_minutes * 60.0
    if soak_runs is not None:
        changes["soak_runs"] = soak_runs
    spec = StudySpec.quick(**changes) if quick else StudySpec(**changes)
    t0 = time.monotonic()
    summary = run_study(spec, runner=task_runner(jobs))
    summary["wall_time_s"] = round(time.monotonic() - t0, 1)
    summary["command"] = "impactcli sensitivity " + " ".join(
        shlex.quote(a) for a in sys.argv[2:]) if sys.argv[1:2] == ["sensitivity"] else ""
    if md_out is not None:
        atomic_write_text(md_out, format_markdown(summary, summary["command"]))
    if json_out == "-":
        click.echo(json.dumps(summary, indent=1, sort_keys=False))
        return
    if json_out is not None:
        atomic_write_text(json_out, json.dumps(summary, indent=1) + "\n")
    click.echo(format_text(summary), nl=False)
    click.echo(f"wall time {summary['wall_time_s']:.0f} s", err=True)
