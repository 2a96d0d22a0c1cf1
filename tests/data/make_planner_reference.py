"""Write tests/data/planner_reference.npz: the outputs of the cartesian, fault-tolerant and
weighted-GPM planners (symbolic backend) before the fused-step rewrite (commit 85a2322), so
tests/test_fast_planning.py checks the rewrite against the code it replaced, not against itself.

    PYTHONPATH=. python tests/data/make_planner_reference.py

Per case: every column at ~REFERENCE_ROWS evenly spaced samples (always the first and last),
and the numeric scalars of the summary. Only rerun on purpose (it freezes today's numbers).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from armgen.planning.tasks import apply_overrides, load_task, run_task

ROOT = Path(__file__).resolve().parent.parent.parent
EXAMPLES = ROOT / "examples"
OUT = Path(__file__).resolve().parent / "planner_reference.npz"
REFERENCE_ROWS = 60

# (case name, example, overrides): every example of the three planners, the combined circle
# with RK4 and with CLIK, and the method variants the examples do not cover.
CASES = [
    ("combined", "modular8_circle_combined", []),
    ("combined_rk4", "modular8_circle_combined", ["integrator.method=rk4"]),
    ("combined_clik", "modular8_circle_combined", ["integrator.clik_gain=10"]),
    ("pinv", "modular8_circle_pinv", []),
    ("repetitive", "modular8_circle_repetitive", []),
    ("zghal", "modular8_circle_zghal", []),
    ("zghal_improved", "modular8_circle_zghal_improved", []),
    ("iiwa_gpm", "iiwa14_fault_circle_gpm", []),
    ("iiwa_wln", "iiwa14_fault_circle_wln", []),
    ("m8_fault_gpm", "modular8_fault_circle_gpm", []),
    ("m8_fault_wln", "modular8_fault_circle_wln", []),
    ("m8_fault_wln_plain", "modular8_fault_circle_wln", ["method.weight_rule=plain"]),
    ("m8_fault_relative", "modular8_fault_circle_gpm", ["method.index=relative"]),
    ("m8_fault_sigma", "modular8_fault_circle_gpm", ["method.index=sigma_min", "timing.duration=1",
                                                      "fault.time=0.5", "path.turns=0.5"]),
    ("m8_fault_pinv", "modular8_fault_circle_gpm", ["method.name=pinv"]),
    ("wgpm", "modular8_wgpm_demo", []),
    ("wgpm_pinv", "modular8_wgpm_demo", ["method.name=pinv", "check.limits=report"]),  # leaves the limits
    ("wgpm_clamp", "modular8_wgpm_demo", ["method.name=clamp", "check.limits=report"]),  # 1.01 × a joint's qddlim
]
# Summary entries that are not results of the plan (wall times).
UNSTABLE = {"run_time_s", "plan_seconds"}


def run(example: str, overrides: list[str]):
    task, sha = load_task(EXAMPLES / f"{example}.toml")
    apply_overrides(task, list(overrides))
    return run_task(task, example, sha, "symbolic")


def sample_rows(count: int) -> np.ndarray:
    return np.unique(np.linspace(0, count - 1, min(REFERENCE_ROWS, count)).round().astype(int))


def summary_scalars(summary: dict) -> dict[str, float]:
    return {k: float(v) for k, v in summary.items()
            if k not in UNSTABLE and isinstance(v, (int, float, bool))}


def main() -> None:
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    arrays = {}
    for name, example, overrides in CASES:
        result = run(example, overrides)
        rows = sample_rows(result.data.shape[0])
        scalars = summary_scalars(result.metadata["summary"])
        arrays[f"{name}/rows"] = rows
        arrays[f"{name}/samples"] = result.data[rows]
        arrays[f"{name}/columns"] = np.array(result.columns)
        arrays[f"{name}/n_rows"] = np.array(result.data.shape[0])
        arrays[f"{name}/summary_keys"] = np.array(list(scalars))
        arrays[f"{name}/summary_values"] = np.array(list(scalars.values()))
        print(f"{name}: {result.data.shape[0]} rows")
    np.savez_compressed(OUT, **arrays)
    print(f"wrote {OUT} ({OUT.stat().st_size / 1e3:.0f} kB)")


if __name__ == "__main__":
    main()
