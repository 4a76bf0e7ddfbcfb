"""Simulation commands: ``vei run``, ``vei casestudy`` and ``vei demo``.

- ``vei run SCENARIO --config NAME|FILE --out DIR``: one configuration; writes
  timeseries.parquet, metrics.json and the figures.
- ``vei casestudy SCENARIO --out DIR``: the paper's five configurations with one time
  shift; writes summary.json / summary.csv / timeseries.parquet / figures and prints the
  summary table.
- ``vei demo [--out DIR] [--real]``: the built-in synthetic example (or the real
  trafficmonitoring scenario) through the whole pipeline: interaction -> reconstruct ->
  time shift -> five configurations -> table and figures.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Annotated

import typer

from vei.cli.sim_table import _console, print_summary

#: The real scenario of ``vei demo --real`` (a cyclist crosses the car's path, two e-scooters nearby).
REAL_DEMO_SCENARIO = "stadtmitte_12_audi_geradeaus_03"

_THREAT_HELP = (
    "The rider to simulate (agent id such as escooter_78, or the recording's track id 78) "
    "instead of the scenario's primary threat."
)
_SFM_RIDERS_HELP = (
    "Which riders are social-force driven in the SFM configurations: 'primary' (the primary "
    "threat only; default), 'all' (every e-scooter and cyclist of the scenario) or ID,ID "
    "(agent ids besides the primary). The SFM riders repel each other and recorded "
    "pedestrians; the built-in engine only (other backends drive the primary rider only)."
)


def _with_sfm_riders(sim, value: str | None):  # type: ignore[no-untyped-def]
    """``sim`` (or SimConfig()) with ``sfm_riders`` from --sfm-riders (None: unchanged)."""
    import dataclasses

    from vei.config import SimConfig

    if value is None:
        return sim
    v = value.strip()
    riders: str | tuple[str, ...] = (
        v if v in ("primary", "all") else tuple(r.strip() for r in v.split(",") if r.strip())
    )
    return dataclasses.replace(sim or SimConfig(), sfm_riders=riders)


_CRITICAL_HELP = (
    "How to make the recording critical: 'timing' (the paper: time shift only) or "
    "'timing+path' (the smallest offset/rotation of the rider's path that lets a time "
    "shift make the paths meet; its size is printed and written to the summary)."
)
_TIME_SHIFT_HELP = (
    "Time shift of the primary rider in seconds (positive: it comes later), or 'auto': the "
    "shift that makes the replayed paths meet in space-time (computed under replay's ego motion)."
)
_BACKEND_HELP = (
    "Simulation backend: 'builtin' (the embedded engine), 'esmini' (vei's closed loop inside "
    "esmini through its C library; see --esmini) or 'carla' (a CARLA server; see --host/--port)."
)
_ESMINI_HELP = "esmini folder (holding bin/ and lib/; backend esmini only; default $VEI_ESMINI, else ../shared/tools/esmini)."
_COMPARE_HELP = (
    "Also run the built-in engine with the same time shift and print both side by side "
    "(collision, safety index, min gap, ego speed and rider path differences); writes "
    "backend_comparison.csv. Needs --backend esmini or carla."
)
_CARLA_TIMEOUT_HELP = (
    "Seconds to wait for the CARLA server to connect and answer (backend carla only; default 10)."
)
_HOST_HELP = "CARLA server host (backend carla only; default $VEI_CARLA_HOST, else 127.0.0.1)."
_PORT_HELP = "CARLA server port (backend carla only; default $VEI_CARLA_PORT, else 2000)."


def _backend(
    name: str,
    host: str | None,
    port: int | None,
    esmini: Path | None = None,
    carla_timeout: float | None = None,
):
    """The backend argument of run_casestudy: a name, or a runner bound to its options."""
    from vei.errors import ConfigError

    if name != "carla" and (host is not None or port is not None or carla_timeout is not None):
        raise ConfigError("--host/--port/--carla-timeout apply to --backend carla only")
    if name != "esmini" and esmini is not None:
        raise ConfigError("--esmini applies to --backend esmini only")
    if carla_timeout is not None and not carla_timeout > 0:
        raise ConfigError(f"--carla-timeout must be > 0 seconds, got {carla_timeout:g}")
    if name == "carla" and (host is not None or port is not None or carla_timeout is not None):
        from vei.experiments.casestudy import get_backend

        get_backend("carla")  # clear error if the backend is missing
        from vei.sim.backends.carla import carla_runner

        return carla_runner(host=host, port=port, timeout_s=carla_timeout)
    if name == "esmini" and esmini is not None:
        from vei.sim.backends.esmini import esmini_runner

        return esmini_runner(esmini)
    return name


def _load_case(config: str):
    """A configuration name (preset) or a YAML/JSON file of a CaseConfig or RunConfig."""
    from vei.config import CASE_PRESETS, CaseConfig, RunConfig, load_config
    from vei.errors import ConfigError

    if config in CASE_PRESETS:
        from vei.config import case_preset

        return case_preset(config), None
    path = Path(config)
    if path.suffix.lower() not in (".yaml", ".yml", ".json"):
        raise ConfigError(
            f"--config {config!r} is neither a configuration name ({', '.join(CASE_PRESETS)}) nor a .yaml/.yml/.json file"
        )
    if not path.is_file():
        raise ConfigError(f"{path}: configuration file not found")
    import json

    import yaml

    text = path.read_text(encoding="utf-8")
    try:
        raw = json.loads(text) if path.suffix.lower() == ".json" else yaml.safe_load(text)
    except Exception as exc:  # noqa: BLE001 - parse errors of either format
        raise ConfigError(f"{path}: cannot parse: {exc}") from None
    if isinstance(raw, dict) and "case" in raw:
        run_cfg = load_config(path, RunConfig)
        return run_cfg.case, run_cfg
    return load_config(path, CaseConfig), None


_POLICY_HELP = (
    "Ego policy (the longitudinal controller): none (PID cruise), paper-cap (the paper's CAP), "
    "aeb, idm, a 'package.module:Class' or 'path/to/file.py:Class' (docs/policy.md). Replaces "
    "the configuration's controller (ego.policy)."
)


def policy_label(spec: str) -> str:
    """A row label for a policy spec: the built-in name, or the class name of a user spec."""
    from vei.config import BUILTIN_POLICIES

    return spec if spec in BUILTIN_POLICIES else spec.rpartition(":")[2]


def with_policy(case, spec: str, *, name: str | None = None):  # type: ignore[no-untyped-def]
    """``case`` driven by the policy ``spec`` (its policy_params kept only for the same spec)."""
    from dataclasses import replace

    from vei.config import validate_policy_spec

    validate_policy_spec(spec)
    params = case.ego.policy_params if case.ego.policy == spec else None
    ego_mode = "pid" if case.ego_mode == "replay-speed" else case.ego_mode
    if ego_mode == "policy":
        ego_mode = "pid"  # decided again by the new policy
    return replace(
        case,
        name=name or case.name,
        ego_mode=ego_mode,
        ego=replace(case.ego, policy=spec, policy_params=params),
    )


def _read_scenario(folder: Path):
    from vei.io.scenario import read_scenario

    return read_scenario(folder)


def register(app: typer.Typer) -> None:
    """Add ``vei run``, ``vei casestudy`` and ``vei demo`` to the app."""

    @app.command("run")
    def run_cmd(
        scenario: Annotated[
            Path,
            typer.Argument(
                help="Scenario folder (scenario.json + trajectories.parquet), as written by 'vei reconstruct'."
            ),
        ],
        config: Annotated[
            str,
            typer.Option(
                "--config",
                "-c",
                help="Configuration: one of replay, normal, aggressive, normal-cap, aggressive-cap "
                "(or replay-speed), or a YAML/JSON file of a configuration (keys name, rider, sfm, "
                "ego_mode, ego, cap; 'preset' starts from a named one) or of a run (keys case, sim, time_shift).",
            ),
        ],
        out: Annotated[
            Path,
            typer.Option(
                "--out", "-o", help="Output folder (timeseries.parquet, metrics.json, figures)."
            ),
        ],
        time_shift: Annotated[
            str | None,
            typer.Option(
                "--time-shift",
                help=_TIME_SHIFT_HELP + " Default: the run file's time_shift, else auto.",
            ),
        ] = None,
        threat: Annotated[str | None, typer.Option("--threat", help=_THREAT_HELP)] = None,
        make_critical: Annotated[
            str, typer.Option("--make-critical", help=_CRITICAL_HELP)
        ] = "timing",
        sfm_riders: Annotated[
            str | None, typer.Option("--sfm-riders", help=_SFM_RIDERS_HELP)
        ] = None,
        backend: Annotated[str, typer.Option("--backend", help=_BACKEND_HELP)] = "builtin",
        host: Annotated[str | None, typer.Option("--host", help=_HOST_HELP)] = None,
        port: Annotated[int | None, typer.Option("--port", help=_PORT_HELP)] = None,
        esmini: Annotated[Path | None, typer.Option("--esmini", help=_ESMINI_HELP)] = None,
        carla_timeout: Annotated[
            float | None, typer.Option("--carla-timeout", help=_CARLA_TIMEOUT_HELP)
        ] = None,
        figures: Annotated[
            bool, typer.Option("--figures/--no-figures", help="Write the figures.")
        ] = True,
        policy: Annotated[str | None, typer.Option("--policy", help=_POLICY_HELP)] = None,
    ) -> None:
        """Run one configuration on a scenario and score it."""
        from vei.experiments.casestudy import run_casestudy, summary_document, write_casestudy
        from vei.io.atomic import write_json

        case, run_cfg = _load_case(config)
        if policy is not None:
            case = with_policy(case, policy)
        shift = (
            time_shift
            if time_shift is not None
            else (run_cfg.time_shift if run_cfg is not None else "auto")
        )
        sim = _with_sfm_riders(run_cfg.sim if run_cfg is not None else None, sfm_riders)
        population = run_cfg.rider if run_cfg is not None else None
        cases = [case]
        if population is not None:
            from vei.calibrate.population import population_cases

            cases = population_cases(case, population)
        scen = _read_scenario(scenario)
        result = run_casestudy(
            scen,
            cases=cases,
            time_shift=shift,
            backend=_backend(backend, host, port, esmini, carla_timeout),
            sim=sim,
            threat=threat,
            make_critical=make_critical,
            metrics_config=run_cfg.metrics if run_cfg is not None else None,
        )
        paths = write_casestudy(result, out, figures=figures)
        doc = summary_document(result)
        metrics_doc = {
            "scenario_id": doc["scenario_id"],
            "config": case.name,
            "primary_threat": doc["primary_threat"],
            "time_shift_s": doc["time_shift_s"],
            "time_shift": doc["time_shift"],
            "backend": doc["backend"],
            "metrics_config": doc["metrics_config"],
            "criticality": doc["criticality"],
        }
        if population is None:
            metrics_doc["metrics"] = doc["configs"][0]
            metrics_doc["case_config"] = doc["case_configs"][case.name]
        else:
            # One run per sampled rider (<config>#i); summary.csv / .json keep the table.
            metrics_doc["rider_population"] = dataclasses.asdict(population)
            metrics_doc["metrics"] = doc["configs"]
            metrics_doc["case_config"] = doc["case_configs"]
        write_json(out / "metrics.json", metrics_doc)
        if population is None:
            for key in ("summary_json", "summary_csv"):
                paths.pop(key).unlink(missing_ok=True)
        print_summary(result, out)

    @app.command("casestudy")
    def casestudy_cmd(
        scenario: Annotated[
            Path, typer.Argument(help="Scenario folder (scenario.json + trajectories.parquet).")
        ],
        out: Annotated[
            Path,
            typer.Option(
                "--out",
                "-o",
                help="Output folder (summary.json, summary.csv, timeseries.parquet, figures).",
            ),
        ],
        time_shift: Annotated[str, typer.Option("--time-shift", help=_TIME_SHIFT_HELP)] = "auto",
        threat: Annotated[str | None, typer.Option("--threat", help=_THREAT_HELP)] = None,
        make_critical: Annotated[
            str, typer.Option("--make-critical", help=_CRITICAL_HELP)
        ] = "timing",
        sfm_riders: Annotated[
            str | None, typer.Option("--sfm-riders", help=_SFM_RIDERS_HELP)
        ] = None,
        backend: Annotated[str, typer.Option("--backend", help=_BACKEND_HELP)] = "builtin",
        host: Annotated[str | None, typer.Option("--host", help=_HOST_HELP)] = None,
        port: Annotated[int | None, typer.Option("--port", help=_PORT_HELP)] = None,
        esmini: Annotated[Path | None, typer.Option("--esmini", help=_ESMINI_HELP)] = None,
        carla_timeout: Annotated[
            float | None, typer.Option("--carla-timeout", help=_CARLA_TIMEOUT_HELP)
        ] = None,
        compare: Annotated[bool, typer.Option("--compare", help=_COMPARE_HELP)] = False,
        figures: Annotated[
            bool, typer.Option("--figures/--no-figures", help="Write the figures.")
        ] = True,
        policy: Annotated[
            list[str] | None,
            typer.Option(
                "--policy",
                help="Compare ego policies instead of the five configurations: one row per "
                "--policy (repeat it: --policy none --policy aeb), each on the --base "
                "configuration, labelled by the policy. " + _POLICY_HELP,
            ),
        ] = None,
        base: Annotated[
            str,
            typer.Option(
                "--base",
                help="With --policy: the configuration (rider) every policy runs on "
                "(a preset name; default normal: the calibrated social-force rider).",
            ),
        ] = "normal",
    ) -> None:
        """Run the paper's five configurations (replay, normal, aggressive, normal-cap, aggressive-cap) and print the summary."""
        from vei.experiments.casestudy import run_casestudy, write_casestudy

        scen = _read_scenario(scenario)
        runner = _backend(backend, host, port, esmini, carla_timeout)
        cases = None
        if policy:
            from vei.config import CASE_PRESETS, case_preset
            from vei.errors import ConfigError

            if base not in CASE_PRESETS:
                raise ConfigError(f"--base {base!r}: expected one of {', '.join(CASE_PRESETS)}")
            labels = [policy_label(p) for p in policy]
            if len(set(labels)) != len(labels):
                raise ConfigError(f"--policy: the policies {policy} repeat a label ({labels})")
            cases = [
                with_policy(case_preset(base), p, name=lab)
                for p, lab in zip(policy, labels, strict=True)
            ]
            if compare:
                raise ConfigError("--compare runs the five configurations: drop --policy")
        if compare:
            if sfm_riders not in (None, "primary"):
                from vei.errors import ConfigError

                raise ConfigError("--compare runs the primary rider only: drop --sfm-riders")
            _casestudy_compared(
                scen, runner, out, time_shift=time_shift, threat=threat,
                make_critical=make_critical, figures=figures,
            )  # fmt: skip
            return
        result = run_casestudy(
            scen,
            cases=cases,
            time_shift=time_shift,
            backend=runner,
            sim=_with_sfm_riders(None, sfm_riders),
            threat=threat,
            make_critical=make_critical,
        )
        write_casestudy(result, out, figures=figures)
        print_summary(result, out)

    @app.command("demo")
    def demo_cmd(
        out: Annotated[
            Path,
            typer.Option(
                "--out",
                "-o",
                help="Output folder (interaction/, scenario/, the case-study files and figures).",
            ),
        ] = Path("demo-out"),
        real: Annotated[
            bool,
            typer.Option(
                "--real",
                help=f"Use the real trafficmonitoring scenario {REAL_DEMO_SCENARIO} (imported from the "
                "dataset) instead of the built-in synthetic example.",
            ),
        ] = False,
        data_dir: Annotated[
            Path | None,
            typer.Option(
                "--data-dir",
                help="With --real: folder holding trafficmonitoring/ (default: $VEI_DATA_DIR, else ../shared/data).",
            ),
        ] = None,
        time_shift: Annotated[str, typer.Option("--time-shift", help=_TIME_SHIFT_HELP)] = "auto",
        interp: Annotated[
            str,
            typer.Option(
                "--interp",
                help="Reconstruction interpolation: auto (default: the paper's cubic for its "
                "1 FPS annotations, smoothing for dense tracks), cubic, linear or smoothing.",
            ),
        ] = "auto",
    ) -> None:
        """The whole pipeline on a built-in SYNTHETIC example shaped like the paper's case study (or --real data)."""
        run_demo(out=out, real=real, data_dir=data_dir, time_shift=time_shift, interp=interp)


def _casestudy_compared(scen, runner, out: Path, *, figures: bool, **options) -> None:
    """`vei casestudy --compare`: the backend's case study, written and printed, and the
    side-by-side table with the built-in engine (backend_comparison.csv)."""
    from vei.errors import ConfigError
    from vei.experiments.backend_compare import compare_backends, format_comparison
    from vei.experiments.casestudy import write_casestudy
    from vei.io.atomic import write_text

    if runner == "builtin":
        raise ConfigError(
            "--compare compares a backend with the built-in engine: pass --backend esmini or carla"
        )
    cmp = compare_backends(scen, backend=runner, reference="builtin", **options)
    write_casestudy(cmp.other, out, figures=figures)
    write_text(Path(out) / "backend_comparison.csv", cmp.table.to_csv(index=False))
    print_summary(cmp.other, out)
    _console().print(format_comparison(cmp), markup=False, highlight=False)


def find_trafficmonitoring_root(data_dir: Path | None) -> Path:
    """The trafficmonitoring dataset root from --data-dir, $VEI_DATA_DIR or ../shared/data."""
    from vei.errors import InputError

    tried = []
    if data_dir is not None:
        candidates = [data_dir]
    elif os.environ.get("VEI_DATA_DIR"):
        candidates = [Path(os.environ["VEI_DATA_DIR"])]
    else:
        candidates = [
            Path.cwd().parent / "shared" / "data",
            Path(__file__).resolve().parents[3].parent / "shared" / "data",
        ]
    for base in candidates:
        for root in (base / "trafficmonitoring", base):
            tried.append(str(root))
            if (root / "data" / "measurements").is_dir():
                return root
    raise InputError(
        "the trafficmonitoring data set was not found (looked for data/measurements under "
        + ", ".join(tried)
        + "); pass --data-dir, set VEI_DATA_DIR, or fetch it with 'vei datasets download trafficmonitoring'",
        path=candidates[0],
    )


def run_demo(
    *,
    out: Path,
    real: bool = False,
    data_dir: Path | None = None,
    time_shift: str = "auto",
    interp: str = "auto",
    console=None,
):
    """What ``vei demo`` does; returns the CaseStudyResult.

    Writes ``out/interaction`` (the input, synthetic or imported), ``out/scenario`` (the
    reconstruction) and the case study files into ``out``.
    """
    from vei.experiments.casestudy import parse_time_shift, run_casestudy, write_casestudy
    from vei.io.interaction import read_interaction
    from vei.io.progress import activity as status
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import ReconstructionConfig, reconstruct

    console = console or _console()
    out = Path(out)
    inter_dir, scen_dir = out / "interaction", out / "scenario"
    # every argument checked before anything is written
    shift = parse_time_shift(time_shift)
    recon = ReconstructionConfig(interp=interp)
    root = find_trafficmonitoring_root(data_dir) if real else None

    with status("step 1/3: preparing the interaction"):
        if real:
            from vei.datasets.trafficmonitoring import import_scenario

            import_scenario(root, REAL_DEMO_SCENARIO, inter_dir, rate_hz=1.0)
            console.print(
                f"imported the real trafficmonitoring scenario {REAL_DEMO_SCENARIO} from {root}"
            )
        else:
            from vei.experiments.demo_data import write_demo_interaction

            write_demo_interaction(inter_dir)
            console.print(
                "generated the built-in SYNTHETIC demo interaction (not a recording): "
                + str(inter_dir)
            )
    with status("step 2/3: reconstructing the scenario"):
        scenario = reconstruct(read_interaction(inter_dir), recon)
        map_files = None
        if not real:  # the synthetic street as a map: roads under the figures (issue 26)
            from vei.experiments.demo_map import attach_demo_map
            from vei.io.scenario import read_scenario

            scenario, map_files = attach_demo_map(scenario)
        write_scenario(scenario, scen_dir, extra_files=map_files)
        if map_files:
            scenario = read_scenario(scen_dir)  # its folder: the figures find the map
    console.print(
        f"reconstructed {scenario.id}: primary threat {scenario.primary_threat}, {scenario.rate_hz:g} Hz -> {scen_dir}"
    )
    with status("step 3/3: time shift, five configurations, metrics and figures"):
        result = run_casestudy(scenario, time_shift=shift)
        write_casestudy(result, out)
    print_summary(result, out, console=console)
    return result
