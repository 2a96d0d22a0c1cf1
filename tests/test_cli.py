"""The command line: listing, showing, generating, and clean failures with exit codes."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from armgen.cli.main import cli


def run(*args):
    return CliRunner().invoke(cli, list(args))


def test_robots_and_show():
    out = run("robots")
    assert out.exit_code == 0
    for name in ("modular8", "iiwa14", "panda", "planar3"):
        assert name in out.output
    out = run("show", "panda")
    assert out.exit_code == 0
    assert "modified DH" in out.output and "a_{i-1}" in out.output and "tool: xyz = [0.0, 0.0, 107.0] mm" in out.output


def test_gen_to_out_dir_with_prefix_and_precision(tmp_path):
    out = run("gen", "planar3", "--out", str(tmp_path), "--precision", "float", "--prefix", "arm")
    assert out.exit_code == 0, out.output
    header = (tmp_path / "arm.h").read_text()
    assert "#define ARM_USE_FLOAT 1" in header and "#define ARM_NDOF 3" in header
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["options"] == {"precision": "float", "prefix": "arm", "functions": manifest["options"]["functions"]}
    assert set(manifest["files"]) == {"arm.h", "arm.c"}


def test_gen_selected_functions(tmp_path):
    out = run("gen", "planar3", "--out", str(tmp_path), "--function", "fk", "--function", "jacobian")
    assert out.exit_code == 0, out.output
    assert json.loads((tmp_path / "manifest.json").read_text())["options"]["functions"] == ["fk", "jacobian"]
    out = run("gen", "planar3", "--out", str(tmp_path), "--function", "nope")
    assert out.exit_code != 0 and "nope" in out.output


def test_errors_have_exit_codes_and_write_nothing(tmp_path):
    out = run("show", "no_such_robot")
    assert out.exit_code == 2 and "unknown robot 'no_such_robot'" in out.output
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "x"\nconvention = "standard"\n[[joints]]\ntype = "revolute"\na = 0\nd = 0\nalpha = 0\nqlim = [1, -1]\n')
    target = tmp_path / "out"
    out = run("gen", str(bad), "--out", str(target))
    assert out.exit_code == 2 and "qlim" in out.output and "reversed" in out.output
    assert not target.exists()


# Every command that writes something (or, for verify, reads what gen wrote) and the
# spellings it had before -o/--out, which must keep working but stay out of --help.
OUTPUT_COMMANDS = {"plan": ("--output",), "plot": ("--output",), "sweep": ("--output",), "animate": ("--output",),
                   "gen": (), "gen-ptp": (), "firmware": (), "verify": ("--generated",)}


def test_one_output_option_everywhere_old_spellings_hidden():
    for name, old in OUTPUT_COMMANDS.items():
        command = cli.commands[name]
        (option,) = [p for p in command.params if "--out" in getattr(p, "opts", ())]
        assert option.opts[:2] == ["-o", "--out"] and set(option.opts[2:]) == set(old), name
        text = run(name, "--help").output
        assert "-o, --out" in text, name
        assert not any(spelling in text for spelling in old), name


def test_old_output_spellings_still_work(tmp_path):
    for spelling in ("-o", "--out", "--output"):
        # the option parses (a missing CSV is the error, not the option); nothing is written
        out = run("plot", str(tmp_path / "missing.csv"), spelling, str(tmp_path / "p.png"))
        assert out.exit_code == 2 and "no such option" not in out.output.lower(), spelling
    for spelling in ("-o", "--out"):
        target = tmp_path / spelling.strip("-")
        out = run("gen-ptp", spelling, str(target))
        assert out.exit_code == 0 and (target / "armgen_ptp.h").is_file(), out.output


def test_robot_repr_is_one_line_and_show_prints_the_table(capsys):
    from armgen import load_robot

    assert repr(load_robot("panda")) == "Robot('panda', 7 revolute, modified DH)"
    assert str(load_robot("snake12")) == "Robot('snake12', 24 revolute + 1 prismatic, standard DH)"
    robot = load_robot("modular8")
    robot.show()
    printed = capsys.readouterr().out
    assert printed == run("show", "modular8").output  # one text, two doors
    # name, file, columns, the joints, the dynamics line, the collision line, the configurations, base/tool if any
    assert len(printed.splitlines()) == 5 + robot.n + len(robot.configurations) + \
        sum(not (T == np.eye(4)).all() for T in (robot.base, robot.tool))


# -- what `armgen plan` prints (issue 37 item 8) -------------------------------------------------

def _line_task(tmp_path, units: str, scale_length: float, scale_angle: float, name: str = "line"):
    """A planar3 line task, its numbers in the given units (the arm's q0 tool point + (50, 20) mm)."""
    from armgen import load_robot

    robot = load_robot("planar3")
    end = (robot.fk(robot.q0)[:3, 3] + [0.05, 0.02, 0.0]) / scale_length
    start = np.asarray(robot.q0) / scale_angle
    path = tmp_path / f"{name}.toml"
    path.write_text(f'planner = "cartesian"\nrobot = "planar3"\nstart = {start.tolist()}\n{units}\n'
                    f'[path]\ntype = "line"\nend = {end.tolist()}\n[timing]\nduration = 1.0\n'
                    '[integrator]\nmethod = "rk4"\nstep = 0.01\n')
    return path


def _table(output: str) -> dict[str, str]:
    """label → 'value unit' of the printed summary table."""
    rows = {}
    for line in output.splitlines():
        if line.startswith("  "):
            label, _, rest = line.strip().partition("  ")
            rows[label] = rest.strip()
    return rows


def test_plan_prints_a_table_in_the_files_units_and_json_for_scripts(tmp_path, monkeypatch):
    """No Python reprs (np.float64(…), dicts); each figure converted from plan.json's units to the
    task file's: the same plan in mm/deg and in m/rad prints the same numbers scaled."""
    import math

    monkeypatch.chdir(tmp_path)
    shown = {}
    for name, units, ls, as_ in (("mm", '[units]\nlength = "mm"\nangle = "deg"', 1e-3, math.pi / 180),
                                 ("si", "", 1.0, 1.0)):
        out = run("plan", str(_line_task(tmp_path, units, ls, as_, name)), "-o", f"{name}.csv")
        assert out.exit_code == 0, out.output
        assert "np.float64" not in out.output and "{'" not in out.output
        assert "warning" not in out.output  # numbers that fit their units: no hint
        shown[name] = (_table(out.output), json.loads((tmp_path / f"{name}.json").read_text())["summary"])
    table_mm, summary = shown["mm"]
    table_si, _ = shown["si"]
    value, unit = table_mm["max pos error"].split()
    assert unit == "mm" and float(value) == pytest.approx(summary["max_pos_error_mm"], rel=1e-3)
    value, unit = table_si["max pos error"].split()
    assert unit == "m" and float(value) == pytest.approx(shown["si"][1]["max_pos_error_mm"] * 1e-3, rel=1e-3)
    q_deg = summary["max_abs_q_deg"]  # three joints: shown whole
    assert table_mm["max abs q"] == "[" + ", ".join(f"{v:.4g}" for v in q_deg) + "] deg"
    assert table_si["max abs q"] == "[" + ", ".join(f"{math.radians(v):.4g}" for v in q_deg) + "] rad"
    assert table_mm["limit violations"] == "none" and table_mm["within speed limits"] == "yes"
    out = CliRunner().invoke(cli, ["plan", str(tmp_path / "mm.toml"), "-o", "again.csv", "--json"])
    assert out.exit_code == 0, out.output
    printed = json.loads(out.stdout)  # stdout is JSON only
    assert printed["csv"] == "again.csv" and printed["samples"] == 101
    assert printed["summary"] == json.loads((tmp_path / "again.json").read_text())["summary"]


def test_a_task_without_units_whose_numbers_look_like_mm_or_deg_gets_a_hint(tmp_path, monkeypatch):
    """Heuristic (docs/input-files.md): a position beyond 3 m reads as millimetres, an angle beyond a
    full turn as degrees; a hint per unit [units] leaves to the default, none when it names it."""
    import math

    monkeypatch.chdir(tmp_path)
    both = _line_task(tmp_path, "", 1e-3, math.pi / 180, "both")  # mm and deg numbers, no [units]
    out = CliRunner().invoke(cli, ["plan", str(both), "-o", "both.csv"])
    hints = [line for line in out.stderr.splitlines() if line.startswith("warning: ")]
    assert len(hints) == 2, out.stderr
    assert "path.end" in hints[0] and '[units] length = "mm"' in hints[0] and str(both) in hints[0]
    assert "start holds" in hints[1] and '[units] angle = "deg"' in hints[1]
    angles = _line_task(tmp_path, '[units]\nlength = "m"', 1.0, math.pi / 180, "angles")
    out = CliRunner().invoke(cli, ["plan", str(angles), "-o", "angles.csv"])
    assert [line for line in out.stderr.splitlines() if line.startswith("warning: ")] == [
        hint for hint in out.stderr.splitlines() if 'angle = "deg"' in hint]
    assert 'length = "mm"' not in out.stderr and 'angle = "deg"' in out.stderr
    out = CliRunner().invoke(cli, ["plan", str(both), "-o", "both.csv", "--set", 'units={length="mm", angle="deg"}'])
    assert "warning" not in out.stderr and out.exit_code == 0, out.output


def test_summary_rows_convert_every_unit_and_shorten_long_lists():
    """Each summary key's unit (its suffix) to the file's, checked against hand conversions."""
    import math

    from armgen.cli.summary import summary_rows

    summary = {"max_abs_q_deg": [10.0, -120.0, 30.0, 40.0], "final_tip_mm": [879.47, 300.0, -0.0],
               "peak_velocity_rad_s": {"j1": 1.0, "j2": -2.0, "j3": 0.5, "j4": 0.1},
               "min_clearance_mm": {"wall": 19.96, "disc": 57.12}, "peak_ddq_deg_s2": 180.0,
               "w_min_mm3": 1e6, "duration_s": 2.5, "tracks": True, "limit_violations": [], "H_M_before_lock": 0.25,
               "joint_speed": {"peak_speed_ratio": [0.2, 0.85], "peak_acceleration_ratio": [None, None],
                               "within_speed_limits": True, "beyond_speed_limits": []}}
    rows = {label: (value, unit) for label, value, unit in
            summary_rows({"task": {"units": {"length": "m", "angle": "rad"}}, "summary": summary})}
    assert rows["max abs q"] == (f"max |·| {math.radians(-120):.4g} (joint 2 of 4)", "rad")
    assert rows["final tip"] == ("[0.8795, 0.3, 0]", "m")
    assert rows["peak velocity"] == ("max |·| -2 (j2 of 4)", "rad/s")
    assert rows["min clearance"] == ("wall 0.01996, disc 0.05712", "m")
    assert rows["peak ddq"] == (f"{math.pi:.4g}", "rad/s²")
    assert rows["w min"] == ("0.001", "m³")  # 1e6 mm³ = 1e-3 m³
    assert rows["duration"] == ("2.5", "s") and rows["tracks"] == ("yes", "")
    assert rows["limit violations"] == ("none", "") and rows["H_M before lock"] == ("0.25", "")
    assert rows["peak joint speed"] == ("85% of qdlim (joint 2)", "") and "peak joint acceleration" not in rows
    mm = {label: (value, unit) for label, value, unit in
          summary_rows({"task": {"units": {"length": "mm", "angle": "deg"}}, "summary": summary})}
    assert mm["peak velocity"] == (f"max |·| {math.degrees(-2):.4g} (j2 of 4)", "deg/s")
    assert mm["w min"] == ("1e+06", "mm³") and mm["min clearance"] == ("wall 19.96, disc 57.12", "mm")
