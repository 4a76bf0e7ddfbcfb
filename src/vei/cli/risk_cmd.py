"""``vei risk``: how likely a collision and an injury are in one encounter, per planner,
with 95 % confidence intervals (docs/risk.md)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer


def _progress_printer(enabled: bool | None):
    """One line per message on stderr (phase boundaries, and every 10 s of simulation:
    :attr:`vei.risk.problem.RiskProblem.progress`), unless disabled."""
    from vei.cli.output import console as make_console

    console = make_console(stderr=True)
    start = time.perf_counter()

    def say(msg: str) -> None:
        if enabled is not False:
            console.print(f"[{time.perf_counter() - start:6.1f} s] {msg}")

    return say


def risk(
    scenario: Annotated[Path, typer.Argument(help="A scenario folder (vei reconstruct).")],
    out: Annotated[
        Path, typer.Option("--out", help="Output folder (risk.json, samples, configs).")
    ],
    spec: Annotated[
        Path | None,
        typer.Option(
            "--spec",
            help="Risk spec (YAML): base, time_shift_reference, seed, variation, fixed, "
            "perception, failure: {count: all|recorded} (docs/risk.md). Default: the "
            "documented default variation.",
        ),
    ] = None,
    policy: Annotated[
        list[str] | None,
        typer.Option(
            "--policy",
            help="Planner to assess (repeat to compare on common random numbers): none, "
            "paper-cap, aeb, idm, or path/file.py:Class. Default: the base configuration's.",
        ),
    ] = None,
    target_rel_ci: Annotated[
        float,
        typer.Option(
            "--target-rel-ci",
            help="Stop when P(collision)'s 95 % interval is within +- this share of the "
            "estimate (0.1 = +-10 %).",
        ),
    ] = 0.1,
    budget: Annotated[
        int, typer.Option("--budget", help="Most simulations per planner (>= 100).")
    ] = 50_000,
    method: Annotated[
        str,
        typer.Option(
            "--method",
            help="auto (Monte Carlo pilot, then cross-entropy importance sampling when "
            "collisions are rare), mc, ce, subset.",
        ),
    ] = "auto",
    sobol: Annotated[
        int,
        typer.Option(
            "--sobol",
            help="Saltelli base sample N of the Sobol indices (N (d + 2) simulations; 0: none).",
        ),
    ] = 256,
    configs: Annotated[
        str,
        typer.Option(
            "--configs",
            help="Which samples get a `vei run --config` file: failures (up to 200 "
            "collisions, those the final estimate rests on first, and 20 others), all, none.",
        ),
    ] = "failures",
    progress: Annotated[
        bool | None,
        typer.Option("--progress/--no-progress", help="Progress lines on stderr."),
    ] = None,
) -> None:
    """P(collision), P(injury-relevant collision) and the expected injury risk of one
    encounter under a variation model, each with a 95 % confidence interval; the failure
    modes; which varied quantity drives the risk (Sobol indices); with several --policy,
    which planner is safer (only where the interval of the difference excludes 0).

    Exit 0 with an honest partial answer when the budget ends before the target (the message says what was not reached); exit 2 on bad input.
    """
    from vei.cli.output import console as make_console
    from vei.risk.run import assess_risk
    from vei.risk.variation import load_variation, parse_variation

    model = load_variation(spec) if spec is not None else parse_variation({}, "default variation")
    say = _progress_printer(progress)
    result = assess_risk(
        scenario,
        model,
        policies=tuple(policy or ()),
        method=method,
        budget=budget,
        target_rel_ci=target_rel_ci,
        sobol_n=sobol,
        out_dir=out,
        configs=configs,
        progress=say,
    )
    print_result(result, make_console())


def print_result(result, console) -> None:
    """The console summary of a :class:`vei.risk.run.RiskResult` (plain lines)."""
    prob = result.problem
    console.print(
        f"encounter {prob.scenario_id}, rider {prob.rider_id} ({prob.rider_category}); "
        f"variation over {', '.join(prob.space.names)}"
    )
    console.print(f"variation model: {prob.model.description()}")
    for line in prob.space.notes:
        console.print(f"note: {line}")
    if getattr(prob.model, "failure_count", "all") == "recorded":
        console.print(
            "failures: only collisions on the rider's recorded behaviour count "
            "(failure: {count: recorded}); those on vei's run-in / run-out are misses"
        )
    if prob.auto_shift is not None and not prob.auto_shift.paths_meet:
        console.print(f"note: {prob.auto_shift.message()}")
    for p in result.planners:
        rel = p.p_collision.rel_ci
        prec = f", +-{100 * rel:.1f} %" if rel < float("inf") else ""
        console.print(f"{p.policy}: {p.method}, {p.n_simulations:,} simulations{prec}")
        for label, e in (
            ("P(collision)", p.p_collision),
            ("P(collision on recorded)", p.p_collision_recorded),
            ("P(injury-relevant collision)", p.p_injury_relevant),
            ("expected injury risk", p.expected_injury),
            ("P(seen too late)", p.p_seen_too_late),
        ):
            if e is None:
                continue
            flag = "" if e.reliable else "  (unreliable: see notes)"
            console.print(f"  {label:30s} {e.text()}{flag}")
        if p.share_synthetic is not None:
            from vei.risk.weighted import share_sentence

            text = share_sentence(p.share_synthetic)
            if text:
                console.print(f"  {text}")
        for note in dict.fromkeys(p.notes + list(p.p_collision.notes)):
            console.print(f"  note: {note}")
        modes = result.modes.get(p.policy, {})
        for k in modes.get("kinds", [])[:3]:
            console.print(f"  failure kind: {k['kind']}: {k['share_of_p_collision']:.0%}")
        for r in modes.get("regions", [])[:3]:
            console.print(
                f"  failure region: {r['rule']}: {r['share_of_p_collision']:.0%} of "
                f"P(collision), P(collision | region) {r['p_collision_in_region']:.2g}"
            )
    for c in result.comparisons:
        console.print(c.sentence())
    if result.sobol:
        from vei.risk.sensitivity import driver, few_failures_note

        top = driver(result.sobol)
        few = few_failures_note(result.sobol)
        if top:
            of = "of the minimum gap " if few else ""
            console.print(
                f"largest total Sobol index {of}: {top} (planner {result.sobol['policy']}, "
                f"{result.sobol['n_simulations']:,} simulations)".replace(" :", ":")
            )
        for note in result.sobol.get("notes", []):
            console.print(f"  note (Sobol): {note}")
    console.print(
        f"{result.n_simulations:,} simulations in {result.timings.get('total', 0):.1f} s; "
        f"results in {result.out_dir}"
    )


def register(app: typer.Typer) -> None:
    """Add ``vei risk`` to the app."""
    app.command("risk")(risk)
