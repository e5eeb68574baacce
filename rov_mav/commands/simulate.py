"""`rov-mav simulate`: the closed loop offline (no MAVLink), with metrics and figures."""

from __future__ import annotations

import argparse
import json

from rov_mav.commands.arguments import (
    mission_file,
    number,
    output_file,
    output_folder,
    require_writable,
    seed,
    vehicle_file,
)
from rov_mav.commands.common import (
    MISSION_HELP,
    add_controller_options,
    add_plan_options,
    add_rerun_option,
    check_rerun_output,
    controller_settings,
    load_mission,
    navigation_errors,
    rerun_recording,
)
from rov_mav.mission.missions import MAX_DURATION


def configure(p: argparse.ArgumentParser) -> None:
    p.description = ("Run the closed loop (mission reference -> law + adaptation -> 6-DOF plant) offline at "
                     "100 Hz, using the mission file's `environment` block (disturbance, current, noise; a .plan: still water). "
                     "Writes figures (PNG) to --out and metrics (JSON) to --metrics.")
    p.add_argument("mission", type=mission_file, help=MISSION_HELP)
    add_plan_options(p)
    add_controller_options(p)
    p.add_argument("--plant-params", type=vehicle_file, metavar="NAME|FILE",
                   help="the simulated plant's vehicle (a shipped vehicle's name or a vehicle YAML) when it differs "
                        "from the controller's model (mismatch studies); default: the controller's model")
    p.add_argument("--duration", type=number(0.0, MAX_DURATION, low_open=True), metavar="S",
                   help=f"simulated seconds, at most {MAX_DURATION:g} (default: the mission's)")
    p.add_argument("--seed", type=seed, default=0, help="seed of the sensor noise (default 0)")
    p.add_argument("--out", type=output_folder, metavar="DIR",
                   help="folder for the figures (default: out/simulate-MISSION-CONTROLLER)")
    p.add_argument("--metrics", type=output_file, metavar="FILE",
                   help="write the metrics JSON here (default: DIR/metrics.json)")
    add_rerun_option(p)
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    # Imported here, when the command runs, so that `rov-mav --help` and the other commands start fast.
    from rov_mav import telemetry
    from rov_mav.mission.metrics import trace_metrics
    from rov_mav.model.vehicle import load_flown_vehicle
    from rov_mav.offline.plots import plot_run
    from rov_mav.offline.simulation import simulate

    mission = load_mission(args)
    settings = controller_settings(args)
    model = load_flown_vehicle(args.vehicle)
    plant = load_flown_vehicle(args.plant_params) if args.plant_params else model
    out_dir = require_writable(args.out or f"out/simulate-{mission.name}-{settings.kind}", folder=True, option="--out")
    metrics_path = require_writable(args.metrics or out_dir / "metrics.json", folder=False, option="--metrics")
    check_rerun_output(args, out_dir / "run.rrd")
    trace = simulate(mission, settings, model, plant, duration=args.duration, seed=args.seed,
                     navigation_errors=navigation_errors)
    metrics = trace_metrics(mission.name, settings.kind, trace)
    figures = plot_run(trace, f"{mission.name} / {settings.kind}", out_dir)
    metrics_path.parent.mkdir(parents=True, exist_ok=True)
    metrics_path.write_text(json.dumps(metrics, indent=2) + "\n")
    rerun_target, recording = rerun_recording(args, out_dir / "run.rrd", trace.reference[:, :3])
    delivered = True
    if recording is not None:
        telemetry.log_trace(recording, trace, model, telemetry.mission_events(mission, trace))
        delivered = telemetry.finish(recording)
    status = "completed" if trace.completed else f"DIVERGED at t = {trace.t[-1]:.2f} s"
    print(f"{mission.name} / {settings.kind}: {status}, {metrics['duration_s']:.1f} s simulated")
    print(f"  position error RMS {metrics['rms_position_error_m'] * 100:.2f} cm "
          f"(steady {metrics['rms_position_error_steady_m'] * 100:.2f} cm, "
          f"max {metrics['max_position_error_m'] * 100:.2f} cm); attitude RMS "
          f"{metrics['rms_attitude_error_rad']:.4f} rad")
    print(f"  final disturbance estimate {[round(v, 3) for v in metrics['final_disturbance_estimate']]}")
    print(f"  metrics: {metrics_path}")
    print(f"  figures: {', '.join(str(f) for f in figures)}")
    print(f"  rerun: {rerun_target.describe(delivered)}")
    return 0 if trace.completed else 1
