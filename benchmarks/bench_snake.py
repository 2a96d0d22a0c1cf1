"""Snake-arm tip following (spec 50): accuracy and run time of both solvers on both bundled
scenarios, side by side with the paper (MATLAB: 3.19 s planar, 2.85 s spatial for 10 s of
motion; the stiff h = 0 model 823.88 s), plus the contrasts the spec asks for:

- the denoised model with scipy's raw error norm on the coordinates (``state = "absolute"``:
  rtol·|s| with |s| ~ 2 m lets each step err by millimetres) vs the per-link state (default);
- h = 0 (no denoising): explicit RK45 and implicit Radau/BDF, each capped in wall-clock time,
  with the simulated time reached (the rate is not constant: BDF reaches 2.5 s in 60 s but only
  2.8 s in 1500 s, so no extrapolation is printed; `--stiff-cap 1500` shows it);
- the paper's arccos angle formula (α loses its sign) vs the signed atan2 form;
- generation time and op counts of snake12's C (the symbolic core's stress case).

    python benchmarks/bench_snake.py [--repeat 5] [--stiff-cap 60] [--explicit-cap 10] [--json out.json]

Run time = the solver (joint-centre coordinates for 1001 outputs, every 10 ms) plus the angle
recovery; "plan" adds the checks (forward kinematics on the recovered angles through the generated
fk, tip deviation, chords, clearance) and metadata. Best of --repeat runs. Any error is a
traceback (exit 1). ``--quick`` (a smoke run): one repeat, the planar scenario only, the h = 0
runs capped at QUICK_CAP_S each.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from armgen.planning.snake import arm as sn_arm, config as sn_config
from armgen.planning.snake import planner as sn
from armgen.planning.tasks import configure_task, load_task

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
SCENARIOS = {"planar": EXAMPLES / "snake_planar.toml", "tank": EXAMPLES / "snake_tank.toml"}
PAPER_S = {"planar": 3.19, "tank": 2.85}
PAPER_TIP_MM = {"planar": 0.005, "tank": 0.018}
PAPER_STIFF_S = 823.88
BARS = {"exact": (1e-6, 0.1), "denoised": (0.02, 1.0)}  # tip deviation mm, run time s
QUICK_CAP_S = 1.0  # --quick: wall-clock cap of each h = 0 run


def _task(name: str, **solver) -> sn_config.SnakeTask:
    raw, _ = load_task(SCENARIOS[name])
    raw = copy.deepcopy(raw)
    raw["solver"].update(solver)
    return configure_task(raw, SCENARIOS[name].name).config


def _best(task: sn_config.SnakeTask, repeat: int) -> dict:
    best = None
    for _ in range(repeat):
        result = sn.plan(task)
        s = result.metadata["summary"]
        if best is None or s["solver_and_recovery_time_s"] < best["solver_and_recovery_time_s"]:
            best = s
    return best


def accuracy_and_speed(repeat: int, scenarios=tuple(SCENARIOS)) -> list[dict]:
    rows = []
    print("\n== accuracy and run time (10 s of motion, output every 10 ms; best of "
          f"{repeat}) ==")
    print(f"{'scenario':8s} {'solver':22s} {'tip dev [mm]':>13s} {'chord err [mm]':>15s} {'vs exact [mm]':>14s} "
          f"{'run [s]':>8s} {'plan [s]':>9s} {'nfev':>6s} {'bars':>12s} {'paper [s]':>9s}")
    for name in scenarios:
        for label, solver in (("exact", {"method": "exact"}),
                              ("denoised (h=0.1, link)", {"method": "denoised"}),
                              ("denoised (h=0.1, abs)", {"method": "denoised", "state": "absolute"})):
            s = _best(_task(name, **solver), repeat)
            tip, chord, run = s["max_tip_deviation_mm"], s["max_chord_error_mm"], s["solver_and_recovery_time_s"]
            bar_tip, bar_run = BARS[solver["method"]]
            ok = "ok" if tip <= bar_tip and run <= bar_run else "MISS"
            vs = s.get("vs_exact", {}).get("max_coordinate_diff_mm", 0.0)
            nfev = s.get("integrator", {}).get("nfev", 0)
            print(f"{name:8s} {label:22s} {tip:13.3g} {chord:15.3g} {vs:14.3g} {run:8.3f} {s['plan_time_s']:9.3f} "
                  f"{nfev:6d} {ok + f' ({bar_tip:g}, {bar_run:g} s)':>12s} {PAPER_S[name]:9.2f}")
            rows.append({"scenario": name, "solver": label, "tip_deviation_mm": tip, "chord_error_mm": chord,
                         "vs_exact_mm": vs, "run_s": run, "plan_s": s["plan_time_s"], "nfev": nfev,
                         "min_clearance_mm": s.get("min_clearance_mm"), "max_abs_joint_angle_deg":
                             s["max_abs_joint_angle_deg"], "paper_run_s": PAPER_S[name],
                         "paper_tip_mm": PAPER_TIP_MM[name]})
    return rows


def stiff_contrast(stiff_cap: float, explicit_cap: float) -> list[dict]:
    print(f"\n== h = 0 (no denoising): the stiff model (paper: {PAPER_STIFF_S} s with an implicit solver) ==")
    print(f"{'scenario':8s} {'integrator':10s} {'cap [s]':>8s} {'wall [s]':>9s} {'t reached [s]':>14s} {'nfev':>9s} "
          f"{'njev':>7s} {'done':>5s}")
    rows = []
    for name, integrator, cap in (("planar", "RK45", explicit_cap), ("planar", "Radau", stiff_cap),
                                  ("planar", "BDF", stiff_cap)):
        task = _task(name, method="denoised", h=0.0, integrator=integrator, max_wall_time=cap)
        track = sn.build_track(task)
        s0 = sn.initial_coordinates(task, track)
        t = np.arange(int(round(task.law.duration / task.output_step)) + 1) * task.output_step
        run, _ = sn.run_dynamics(task, track, s0, t)
        print(f"{name:8s} {integrator:10s} {cap:8.0f} {run.wall_s:9.2f} {run.t_reached:14.5g} {run.nfev:9d} "
              f"{run.njev:7d} {str(run.completed):>5s}")
        rows.append({"scenario": name, "integrator": integrator, "cap_s": cap, "wall_s": run.wall_s,
                     "t_reached_s": run.t_reached, "nfev": run.nfev, "njev": run.njev, "completed": run.completed})
    print("(10 s of motion with the denoised model, h = 0.1 s and RK45: ~0.2 s)")
    return rows


def angle_formula_contrast() -> list[dict]:
    print("\n== angle recovery: the paper's arccos form vs the signed atan2 form (exact solver's joint centres) ==")
    rows = []
    for name in SCENARIOS:
        task = _task(name, method="exact")
        track = sn.build_track(task)
        t = np.arange(1001) * 0.01
        sol = sn.solve(task, track, t)
        centres = track.joints(sol.s, 0)[0]
        place = task.rail_start - task.arm.base0
        out = {"scenario": name}
        for label, fn in (("signed", sn_arm.recover_angles), ("paper", sn_arm.recover_angles_paper)):
            feed, a, b = fn(task.arm, centres, task.rail_start)
            tip = task.arm.joint_centres(task.arm.q_vector(feed, a, b))[0][:, -1] + place
            out[label + "_tip_error_mm"] = float(np.max(np.linalg.norm(tip - centres[:, -1], axis=1)) * 1e3)
        print(f"{name:8s} signed: {out['signed_tip_error_mm']:.3g} mm   paper: {out['paper_tip_error_mm']:.4g} mm")
        rows.append(out)
    return rows


def generation() -> dict:
    from armgen.codegen.generate import CodegenConfig, generate
    from armgen.robot import load_robot

    robot = load_robot("snake12")
    started = time.perf_counter()
    code = generate(CodegenConfig(robot))
    wall = time.perf_counter() - started
    print(f"\n== generated C of snake12 (25 DOF): {len(code.emitted)} functions in {wall:.2f} s, "
          f"{len(code.files['snake12.c']) / 1e3:.0f} kB of C ==")
    ops = {}
    for em in code.emitted:
        ops[em.name] = {"flops": em.flops, "work_reals": em.work_reals, "op_counts": dict(sorted(em.op_counts.items()))}
        counts = ", ".join(f"{k} {v}" for k, v in sorted(em.op_counts.items()) if k not in ("input", "output", "const"))
        print(f"  {em.name:20s} flops {em.flops:6d}  work {em.work_reals:4d}  ({counts})")
    return {"seconds": wall, "functions": ops}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--stiff-cap", type=float, default=60.0, help="wall-clock cap of each implicit h = 0 run [s]")
    parser.add_argument("--explicit-cap", type=float, default=10.0, help="wall-clock cap of the explicit h = 0 run [s]")
    parser.add_argument("--skip-stiff", action="store_true")
    parser.add_argument("--json", default=None, help="also write the numbers here")
    parser.add_argument("--quick", action="store_true", help="one repeat, planar only, h = 0 runs capped (a smoke run)")
    args = parser.parse_args()
    scenarios = tuple(SCENARIOS)
    if args.quick:
        args.repeat, args.stiff_cap, args.explicit_cap, scenarios = 1, QUICK_CAP_S, QUICK_CAP_S, ("planar",)
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    out = {"generation": generation(), "runs": accuracy_and_speed(args.repeat, scenarios),
           "angle_recovery": angle_formula_contrast()}
    if not args.skip_stiff:
        out["stiff"] = stiff_contrast(args.stiff_cap, args.explicit_cap)
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2, default=float) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
