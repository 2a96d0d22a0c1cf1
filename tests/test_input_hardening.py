"""Hostile and mistaken inputs of the poses CSV, `armgen sweep` and the IK entry points
(issue 37, items 14–16): each ends in one clear error naming the file or option, the place
and the fix, quoting at most a bounded excerpt; nothing is half done."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from armgen.errors import TaskFileError
from armgen.planning.toolpath.task import read_poses

# An error message names the file, the place and the fix, quoting a bounded excerpt.
MAX_MESSAGE_CHARS = 600
HEADER = "x,y,z,roll,pitch,yaw"
POSE_ROWS = [f"{650 + 5 * k},{100 + 5 * k},400,180,0,180" for k in range(1, 6)]
MM, DEG = 1e-3, np.pi / 180


def _read(path: Path):
    return read_poses(path, path.name, 1, "task.toml", MM, DEG)


def _poses_error(tmp_path: Path, text: str) -> str:
    path = tmp_path / "contour.csv"
    path.write_text(text)
    with pytest.raises(TaskFileError) as info:
        _read(path)
    message = str(info.value)
    assert message.startswith("task.toml: path.moves[1] (poses): contour.csv"), message
    assert len(message) < MAX_MESSAGE_CHARS, message
    return message


# -- 14: the poses CSV --------------------------------------------------------------------

def test_poses_header_only_is_refused(tmp_path):
    assert "only the header row, no pose" in _poses_error(tmp_path, HEADER + "\n")


@pytest.mark.parametrize("row,column", [("650,100,400,1e300,0,0,0", "qw"), ("650,100,400,0,0,-1e300,0", "qy")])
def test_poses_huge_quaternion_is_refused(tmp_path, row, column):
    message = _poses_error(tmp_path, "x,y,z,qw,qx,qy,qz\n" + row + "\n")
    assert f"line 2, column {column} is beyond" in message


@pytest.mark.parametrize("row,where", [("1e300,100,400,180,0,180", "column x"),
                                       ("650,100,400,180,1e300,180", "column pitch")])
def test_poses_huge_value_is_refused(tmp_path, row, where):
    assert f"line 2, {where} is beyond" in _poses_error(tmp_path, "\n".join([HEADER, row]) + "\n")


def test_poses_field_beyond_the_csv_limit_is_refused_with_its_line(tmp_path):
    rows = [HEADER, *POSE_ROWS[:2], "650,100,400,180," + "0" * 140_000 + ",180", *POSE_ROWS[2:]]
    message = _poses_error(tmp_path, "\n".join(rows) + "\n")
    assert "line 4: not CSV" in message and "131072 characters" in message


def test_poses_long_comment_is_a_comment(tmp_path):
    path = tmp_path / "contour.csv"
    path.write_text("\n".join(["# " + "c" * 140_000, '#"an unclosed quote', HEADER, *POSE_ROWS]) + "\n")
    points, rotations, _, _ = _read(path)
    assert points.shape == (5, 3) and len(rotations) == 5
    np.testing.assert_allclose(points[0], [0.655, 0.105, 0.4])


def test_poses_errors_count_comment_and_blank_lines(tmp_path):
    rows = ["# contour", HEADER, "", *POSE_ROWS[:2], "# a note", "660,nan,400,180,0,180"]
    assert "line 7, column y is nan" in _poses_error(tmp_path, "\n".join(rows) + "\n")


def test_poses_header_is_quoted_as_an_excerpt(tmp_path):
    message = _poses_error(tmp_path, "a" * 100_000 + ",x\n1,2\n")
    assert "(100004 characters)" in message and "lacks y, z" in message


def test_poses_cell_is_quoted_as_an_excerpt(tmp_path):
    message = _poses_error(tmp_path, f"{HEADER}\n650,{'z' * 5000},400,180,0,180\n")
    assert "line 2, column y" in message and "(5002 characters)" in message


@pytest.mark.skipif(not Path("/proc/self/environ").exists(), reason="needs Linux /proc")
def test_poses_pseudo_file_is_refused_without_quoting_it():
    with pytest.raises(TaskFileError) as info:
        read_poses(Path("/proc/self/environ"), "/proc/self/environ", 1, "task.toml", MM, DEG)
    message = str(info.value)
    assert "pseudo-file" in message and len(message) < MAX_MESSAGE_CHARS
    assert "PATH=" not in message and os.environ.get("HOME", "/nonexistent-home") not in message
