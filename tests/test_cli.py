"""The command line: listing, showing, generating, and clean failures with exit codes."""

import json

import numpy as np
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
    assert len(printed.splitlines()) == 3 + robot.n + len(robot.configurations) + \
        sum(not (T == np.eye(4)).all() for T in (robot.base, robot.tool))
